"""Policy sidecars that are not what a saved actor writes: clear errors naming the file."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("torch")

from autoscoop.agents.networks import PAPER_LAYERS, PaperActor
from autoscoop.agents.policy_files import PolicyFileError, load_actor, save_actor


@pytest.fixture
def saved(tmp_path):
    path = save_actor(PaperActor(layers=list(PAPER_LAYERS)), tmp_path / "actor.safetensors")
    return path, path.with_suffix(".json")


def test_a_saved_actor_loads(saved):
    actor, meta = load_actor(saved[0])
    assert list(actor.layers) == list(PAPER_LAYERS) and meta["layers"] == list(PAPER_LAYERS)


@pytest.mark.parametrize("change", [
    lambda meta: {k: v for k, v in meta.items() if k != "layers"},
    lambda meta: {**meta, "layers": "100,80"},
    lambda meta: {**meta, "layers": [100, -1, 60]},
    lambda meta: {**meta, "layers": []},
    lambda meta: [meta],
])
def test_a_sidecar_without_proper_layers_or_not_an_object_is_refused(saved, change):
    path, sidecar = saved
    sidecar.write_text(json.dumps(change(json.loads(sidecar.read_text()))))
    with pytest.raises(PolicyFileError, match=sidecar.name):
        load_actor(path)
