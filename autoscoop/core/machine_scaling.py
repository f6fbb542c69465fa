"""A machine scaled by a factor S, as a starting point for another (``autoscoop machine new --scale S``).

Froude scaling, which keeps a scoop's motion similar under the same gravity: lengths times S, masses times
S^3, times (and so the actuators' stroke times) times sqrt(S); from these, linear speeds times sqrt(S),
angular speeds times 1/sqrt(S), torques times S^4, damping times S^3.5, inertias times S^5. Angles and
friction coefficients stay. The control period and physics step stay too (a period must stay a whole
number of physics steps; a much smaller machine may want a shorter one, see docs/machines.md).

In ``machine.yaml`` the unit suffix of a field's name says how it scales (``_m``, ``_kg``, ``_mps``,
``_radps``, ``_nm``, ``_nms``, ``_kgm2``); in the MJCF the attribute's name and element do.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import Any

SUFFIX_EXPONENTS = {"_m": 1.0, "_kg": 3.0, "_mps": 0.5, "_radps": -0.5, "_nm": 4.0, "_nms": 3.5, "_kgm2": 5.0}
"""Power of S a machine.yaml field is multiplied by, by the unit suffix of its name (others stay)."""

MJCF_EXPONENTS = {"pos": 1.0, "size": 1.0, "fromto": 1.0, "vertex": 1.0, "mass": 3.0, "diaginertia": 5.0,
                  "fullinertia": 5.0, "damping": 3.5, "armature": 5.0, "forcerange": 4.0, "kp": 4.0, "kv": 3.5,
                  "ctrlrange": -0.5}
"""Power of S an MJCF attribute is multiplied by (the actuators' ctrlrange: a speed, rad/s; kp: N*m/rad; kv and
damping: N*m*s/rad). Angles (range, actrange, euler), friction and colours stay."""
MJCF_SKIPPED_TAGS = {"compiler", "option", "visual", "light", "camera", "texture", "material"}
"""Elements whose attributes are not the machine's dimensions."""


def _suffix_exponent(key: str) -> float:
    for suffix, exponent in SUFFIX_EXPONENTS.items():
        if key.endswith(suffix):
            return exponent
    return 0.0


def _times(value: Any, factor: float) -> Any:
    if isinstance(value, list | tuple):
        return [_times(v, factor) for v in value]
    if isinstance(value, bool) or not isinstance(value, int | float):
        return value
    return float(format(float(value) * factor, ".12g"))  # 12 digits: 0.102, not 0.10200000000000001


def scale_machine_data(data: dict[str, Any], scale: float) -> dict[str, Any]:
    """A copy of a parsed machine.yaml with every dimension scaled by ``scale`` (see the module's rules)."""

    def walk(node: Any) -> Any:
        if isinstance(node, dict):
            return {k: (_times(v, scale ** _suffix_exponent(k)) if _suffix_exponent(k) and not isinstance(v, dict)
                        else walk(v)) for k, v in node.items()}
        if isinstance(node, list):
            return [walk(v) for v in node]
        return node

    return walk(data)


def scale_mjcf(xml_text: str, scale: float, header: str, model: str | None = None) -> str:
    """An MJCF with every dimension scaled by ``scale``; comments dropped, ``header`` put first as one;
    ``model``: the root's new ``model`` name (``None``: kept).

    Raises:
        ValueError: the text is not XML.
    """
    try:
        root = ET.fromstring(xml_text)
    except ET.ParseError as error:
        raise ValueError(f"the MJCF is not valid XML: {error}") from None
    for element in root.iter():
        if element.tag in MJCF_SKIPPED_TAGS:
            continue
        for name, value in list(element.attrib.items()):
            exponent = MJCF_EXPONENTS.get(name)
            if exponent is None:
                continue
            try:
                numbers = [float(v) for v in value.split()]
            except ValueError:
                continue
            element.set(name, " ".join(format(v * scale**exponent, ".12g") for v in numbers))
    if model is not None:
        root.set("model", model)
    ET.indent(root, space="  ")
    return f"<!-- {header} -->\n" + ET.tostring(root, encoding="unicode") + "\n"
