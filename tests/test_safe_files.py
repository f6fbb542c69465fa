"""Bounded reading and atomic writing (autoscoop.core.safe_files)."""

from __future__ import annotations

import errno
import os
import resource
import time

import pytest

from autoscoop.core.safe_files import (
    MAX_YAML_DEPTH,
    QUOTE_CHARS,
    UnsafeInputError,
    atomic_output,
    describe_os_error,
    quote,
    read_bytes_bounded,
    read_json,
    read_yaml,
    write_json_atomically,
    write_text_atomically,
)

ALIAS_BOMB = "\n".join(["a: &a [x, x, x, x, x, x, x, x, x]"]
                       + [f"{chr(98 + i)}: &{chr(98 + i)} [*{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, "
                          f"*{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, *{chr(97 + i)}, "
                          f"*{chr(97 + i)}]" for i in range(8)]) + "\n"


def test_an_alias_bomb_is_refused_at_once_in_little_memory(tmp_path):
    path = tmp_path / "bomb.yaml"
    path.write_text(ALIAS_BOMB)
    assert len(ALIAS_BOMB) < 1024
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    start = time.perf_counter()
    with pytest.raises(UnsafeInputError, match="aliases .* are not accepted") as error:
        read_yaml(path, "config file")
    assert time.perf_counter() - start < 2.0
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 50_000  # KiB
    assert str(path) in str(error.value) and "line 2" in str(error.value)


def test_a_duplicate_key_is_refused_naming_it_and_the_line(tmp_path):
    path = tmp_path / "twice.yaml"
    path.write_text("pile:\n  angle_deg: 20\n  angle_deg: 40\n")
    with pytest.raises(UnsafeInputError, match="key 'angle_deg' appears more than once") as error:
        read_yaml(path, "config file")
    assert "line 3" in str(error.value)


def test_the_same_key_in_two_sections_is_fine(tmp_path):
    path = tmp_path / "ok.yaml"
    path.write_text("a: {x: 1}\nb: {x: 2}\nc: [1, [2, {d: e}]]\n")
    assert read_yaml(path, "config file") == {"a": {"x": 1}, "b": {"x": 2}, "c": [1, [2, {"d": "e"}]]}


def test_deep_nesting_is_refused(tmp_path):
    path = tmp_path / "deep.yaml"
    path.write_text("[" * (MAX_YAML_DEPTH + 1) + "]" * (MAX_YAML_DEPTH + 1))
    with pytest.raises(UnsafeInputError, match="nested deeper than"):
        read_yaml(path, "config file")


def test_an_endless_file_is_refused_before_parsing():
    start = time.perf_counter()
    with pytest.raises(UnsafeInputError, match="/dev/zero: larger than"):
        read_yaml("/dev/zero", "config file")
    assert time.perf_counter() - start < 2.0


def test_a_binary_file_is_named(tmp_path):
    path = tmp_path / "calibration.yaml"
    path.write_bytes(b"\x89PNG\x00\xff\xfe")
    with pytest.raises(UnsafeInputError, match="not UTF-8 text") as error:
        read_yaml(path, "calibration")
    assert str(path) in str(error.value)


def test_bounded_reading_refuses_one_byte_over_the_cap(tmp_path):
    path = tmp_path / "f"
    path.write_bytes(b"x" * 11)
    assert read_bytes_bounded(path, 11, "file") == b"x" * 11
    with pytest.raises(UnsafeInputError, match="larger than 10 bytes"):
        read_bytes_bounded(path, 10, "file")


def test_json_errors_name_the_file(tmp_path):
    path = tmp_path / "run.json"
    path.write_text("{not json")
    with pytest.raises(UnsafeInputError, match="not valid JSON") as error:
        read_json(path, "run file")
    assert str(path) in str(error.value)


def test_quote_keeps_messages_short():
    assert len(quote("x" * 100_000)) <= QUOTE_CHARS + 3
    assert len(quote(list(range(100_000)))) <= QUOTE_CHARS + 3
    assert quote(0.5) == "0.5"


def test_atomic_writing_replaces_and_leaves_no_temporary_file(tmp_path):
    path = tmp_path / "sub" / "out.json"
    write_json_atomically(path, {"a": 1})
    write_json_atomically(path, {"a": 2})
    assert path.read_text() == '{\n  "a": 2\n}\n'
    assert sorted(os.listdir(path.parent)) == ["out.json"]


def test_a_failing_writer_keeps_the_old_file_and_names_the_path(tmp_path):
    path = tmp_path / "out.txt"
    path.write_text("old")
    with pytest.raises(OSError) as error, atomic_output(path) as tmp:
        tmp.write_text("half")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert path.read_text() == "old" and sorted(os.listdir(tmp_path)) == ["out.txt"]
    assert describe_os_error(error.value) == f"{path}: No space left on device"


@pytest.fixture
def small_disk(tmp_path):
    """A 64 KiB tmpfs (root only; skipped where mounting is not permitted)."""
    folder = tmp_path / "disk"
    folder.mkdir()
    if os.geteuid() != 0 or os.system(f"mount -t tmpfs -o size=64k tmpfs {folder} 2>/dev/null") != 0:
        pytest.skip("cannot mount a tmpfs here")
    yield folder
    os.system(f"umount {folder}")


def test_a_full_disk_keeps_the_old_file(small_disk):
    path = small_disk / "out.txt"
    write_text_atomically(path, "old")
    with pytest.raises(OSError) as error:
        write_text_atomically(path, "x" * 200_000)
    assert error.value.errno == errno.ENOSPC and str(path) in describe_os_error(error.value)
    assert path.read_text() == "old" and sorted(os.listdir(small_disk)) == ["out.txt"]


def test_a_named_pipe_without_a_writer_does_not_hang(tmp_path):
    fifo = tmp_path / "config.yaml"
    os.mkfifo(fifo)
    start = time.perf_counter()
    assert read_yaml(fifo, "config file") is None  # read as empty
    assert time.perf_counter() - start < 2.0


def test_a_symbolic_link_keeps_pointing_at_the_replaced_file(tmp_path):
    target, link = tmp_path / "target.json", tmp_path / "link.json"
    target.write_text("old")
    link.symlink_to(target)
    write_text_atomically(link, "new")
    assert link.is_symlink() and target.read_text() == "new"


def test_a_device_is_written_in_place_never_replaced():
    write_text_atomically("/dev/null", "nothing")
    assert not os.path.isfile("/dev/null")
    with pytest.raises(OSError) as error:
        write_text_atomically("/dev/full", "x")
    assert describe_os_error(error.value) == "/dev/full: No space left on device"
    assert not os.path.isfile("/dev/full")
