"""Files from outside read within bounds, and every output written atomically.

Reading: a file that autoscoop parses (a config, a sweep space, a robot config, a policy sidecar, a
calibration, an episode record) is read through :func:`read_bytes_bounded` or :func:`read_yaml`, which
refuse it *before parsing* when it is larger than its cap, and refuse YAML aliases (``&a`` / ``*a``: a
few hundred bytes of them expand to gigabytes), duplicate keys (the last one would silently win) and
nesting deeper than :data:`MAX_YAML_DEPTH`. Error messages quote at most :data:`QUOTE_CHARS` characters
of a value (:func:`quote`).

Writing: :func:`atomic_output` gives a temporary path in the target's own folder; when the block ends
without an error the file is flushed to disk (fsync) and renamed over the target, so a crash or a full
disk leaves the previous file intact, never half of a new one. An ``OSError`` from the block names the
target path (``No space left on device`` from ``write`` names no file on its own).
"""

from __future__ import annotations

import json
import os
import reprlib
import secrets
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml

QUOTE_CHARS = 200
"""the most characters of a value an error message quotes."""
MAX_YAML_BYTES = 1 << 20
"""cap of a YAML file autoscoop reads (config, sweep space, robot config, calibration), bytes (1 MiB)."""
MAX_JSON_BYTES = 1 << 20
"""cap of a JSON file autoscoop reads (policy sidecar, run.json), bytes (1 MiB)."""
MAX_YAML_DEPTH = 32
"""the deepest nesting of mappings and lists a YAML file may have."""


class UnsafeInputError(ValueError):
    """A file too large, not text, or with YAML that autoscoop does not accept; the message names the file."""


def quote(value: Any, limit: int = QUOTE_CHARS) -> str:
    """``repr(value)`` for an error message: long strings, lists and mappings abridged (``reprlib``), the
    whole cut to ``limit`` characters."""
    text = _ABRIDGED.repr(value)
    return text if len(text) <= limit else f"{text[:limit]}..."


_ABRIDGED = reprlib.Repr()
_ABRIDGED.maxstring = _ABRIDGED.maxother = QUOTE_CHARS
_ABRIDGED.maxlevel, _ABRIDGED.maxlist, _ABRIDGED.maxdict, _ABRIDGED.maxtuple = 3, 12, 12, 12


def read_bytes_bounded(path: str | Path, limit: int, what: str) -> bytes:
    """The bytes of ``path``, refused when there are more than ``limit`` of them (checked while reading,
    so ``/dev/zero`` or a growing file stops at ``limit``).

    Args:
        path: the file.
        limit: the most bytes accepted.
        what: how messages name the file ("config file", "policy sidecar").

    Raises:
        UnsafeInputError: missing, a folder, unreadable or larger than ``limit`` (the message names the file).
    """
    path = Path(path)
    if path.is_dir():
        raise UnsafeInputError(f"{what} {path}: is a folder, not a file")
    try:
        with _open_without_waiting(path) as handle:
            data = handle.read(limit + 1)
    except FileNotFoundError:
        raise UnsafeInputError(f"{what} {path}: no such file") from None
    except OSError as error:
        raise UnsafeInputError(f"{what} {path}: cannot be read ({error.strerror or error})") from None
    if len(data) > limit:
        raise UnsafeInputError(f"{what} {path}: larger than {limit} bytes; refused before parsing")
    return data


def _open_without_waiting(path: Path) -> Any:
    """``path`` opened for reading in binary; a named pipe without a writer does not block the open (it then
    reads as empty)."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    os.set_blocking(fd, True)
    return os.fdopen(fd, "rb")


def read_text_bounded(path: str | Path, limit: int, what: str) -> str:
    """:func:`read_bytes_bounded`, decoded as UTF-8.

    Raises:
        UnsafeInputError: as :func:`read_bytes_bounded`, or not UTF-8 text (a binary file).
    """
    data = read_bytes_bounded(path, limit, what)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise UnsafeInputError(f"{what} {path}: not UTF-8 text (byte {error.start}); is it a binary file?") from None


class StrictSafeLoader(yaml.SafeLoader):
    """PyYAML's safe loader without aliases, duplicate keys or nesting deeper than :data:`MAX_YAML_DEPTH`."""

    def __init__(self, stream: Any) -> None:
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.composer.ComposerError(None, None, f"aliases (*{quote(event.anchor, 40)}) are not accepted; "
                                              "write the value out", event.start_mark)
        if self.check_event(yaml.MappingStartEvent, yaml.SequenceStartEvent):
            self._depth += 1
            if self._depth > MAX_YAML_DEPTH:
                raise yaml.composer.ComposerError(None, None, f"nested deeper than {MAX_YAML_DEPTH} levels",
                                                  self.peek_event().start_mark)
            try:
                return super().compose_node(parent, index)
            finally:
                self._depth -= 1
        return super().compose_node(parent, index)

    def construct_mapping(self, node: Any, deep: bool = False) -> Any:
        if isinstance(node, yaml.MappingNode):
            self.flatten_mapping(node)
            seen: set[Any] = set()
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=True)
                try:
                    duplicate = key in seen
                    seen.add(key)
                except TypeError:  # an unhashable key: the safe loader's own error follows
                    continue
                if duplicate:
                    raise yaml.constructor.ConstructorError(
                        "while constructing a mapping", node.start_mark,
                        f"key {quote(key, 80)} appears more than once", key_node.start_mark)
        return super().construct_mapping(node, deep)


def parse_yaml(text: str, source: str) -> Any:
    """Parse YAML text with :class:`StrictSafeLoader`.

    Args:
        text: the YAML.
        source: how messages name where it came from ("config file x.yaml").

    Raises:
        UnsafeInputError: not valid YAML, an alias, a duplicate key or nesting too deep (with line and column).
    """
    try:
        return yaml.load(text, Loader=StrictSafeLoader)  # a SafeLoader subclass: builds only plain data
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        problem = getattr(error, "problem", None) or str(error)
        raise UnsafeInputError(f"{source}: not valid YAML{where}: {problem[:QUOTE_CHARS]}") from None
    except RecursionError:
        raise UnsafeInputError(f"{source}: nested too deeply") from None
    except ValueError as error:  # a value YAML's own types refuse, e.g. an integer of more than 4300 digits
        raise UnsafeInputError(f"{source}: not valid YAML: {str(error)[:QUOTE_CHARS]}") from None


def read_yaml(path: str | Path, what: str, limit: int = MAX_YAML_BYTES) -> Any:
    """The parsed contents of a YAML file (``None`` if empty), read within ``limit`` bytes.

    Raises:
        UnsafeInputError: as :func:`read_text_bounded` and :func:`parse_yaml`; the message names the file.
    """
    return parse_yaml(read_text_bounded(path, limit, what), f"{what} {path}")


def read_json(path: str | Path, what: str, limit: int = MAX_JSON_BYTES) -> Any:
    """The parsed contents of a JSON file, read within ``limit`` bytes.

    Raises:
        UnsafeInputError: missing, too large, not text or not valid JSON; the message names the file.
    """
    text = read_text_bounded(path, limit, what)
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as error:
        raise UnsafeInputError(f"{what} {path}: not valid JSON ({str(error)[:QUOTE_CHARS]})") from None


@contextmanager
def atomic_output(path: str | Path) -> Iterator[Path]:
    """A temporary path beside ``path`` for the block to write; renamed over ``path`` once complete.

    The temporary name keeps ``path``'s suffix (libraries pick a format by it) and starts with a dot. On
    success the file is fsynced, renamed over ``path`` and the folder fsynced; on any error it is removed
    and ``path`` is left as it was. Missing folders are created. A symbolic link is followed (its target is
    replaced); a device or a pipe (``/dev/stdout``) cannot be replaced and is written in place.

    Raises:
        OSError: from the block or the rename, naming ``path`` (errno and reason kept).
    """
    path = Path(path)
    if path.exists() and not path.is_file() and not path.is_dir():  # a device or pipe (/dev/stdout): in place
        try:
            yield path
        except OSError as error:
            raise OSError(error.errno, error.strerror or str(error), str(path)) from error
        return
    path = Path(os.path.realpath(path))  # a symbolic link's target is replaced, the link kept
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp{path.suffix}")
    try:
        yield tmp
        _fsync(tmp, os.O_RDONLY)
        os.replace(tmp, path)
    except OSError as error:
        tmp.unlink(missing_ok=True)
        if error.filename is not None and Path(error.filename) != tmp:
            raise
        raise OSError(error.errno, error.strerror or str(error), str(path)) from error
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    try:
        _fsync(path.parent, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:  # some file systems refuse to fsync a folder; the rename is done
        pass


def _fsync(path: Path, flags: int) -> None:
    fd = os.open(path, flags)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def write_bytes_atomically(path: str | Path, data: bytes) -> None:
    """Replace ``path`` with ``data`` through :func:`atomic_output`."""
    with atomic_output(path) as tmp, open(tmp, "wb") as handle:
        handle.write(data)


def write_text_atomically(path: str | Path, text: str) -> None:
    """Replace ``path`` with UTF-8 ``text`` through :func:`atomic_output`."""
    write_bytes_atomically(path, text.encode("utf-8"))


def write_json_atomically(path: str | Path, data: Any, indent: int | None = 2) -> None:
    """Replace ``path`` with ``data`` as JSON (and a final newline) through :func:`atomic_output`."""
    write_text_atomically(path, json.dumps(data, indent=indent) + "\n")


def describe_os_error(error: OSError) -> str:
    """``PATH: reason`` for an ``OSError`` (both paths for a rename or copy), as the command line prints it."""
    reason = error.strerror or str(error)
    paths = [p for p in (error.filename, getattr(error, "filename2", None)) if p is not None]
    return f"{' -> '.join(map(str, paths))}: {reason}" if paths else reason
