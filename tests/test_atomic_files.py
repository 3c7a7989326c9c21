import json
import os
import stat

import pytest

from typed_config.files import atomic_path, write_bytes_atomic, write_json_atomic, write_text_atomic


def test_writes_replace_the_file_and_leave_no_temporary(tmp_path):
    path = tmp_path / "out.json"
    write_text_atomic(path, "old")
    write_json_atomic(path, {"b": 1, "a": [2]})
    assert json.loads(path.read_text()) == {"a": [2], "b": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"]


def test_a_failed_write_keeps_the_previous_file(tmp_path):
    path = tmp_path / "out.txt"
    write_text_atomic(path, "previous")
    with pytest.raises(RuntimeError, match="disk on fire"), atomic_path(path) as tmp:
        tmp.write_text("half")
        raise RuntimeError("disk on fire")
    assert path.read_text() == "previous"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_new_files_get_the_usual_permissions_not_the_temporary_files(tmp_path):
    old = os.umask(0o022)
    try:
        write_bytes_atomic(tmp_path / "a.bin", b"\x00\x01")
        with atomic_path(tmp_path / "b.txt") as tmp:
            tmp.write_text("b")
    finally:
        os.umask(old)
    assert [stat.S_IMODE((tmp_path / name).stat().st_mode) for name in ("a.bin", "b.txt")] == [0o644, 0o644]
    assert (tmp_path / "a.bin").read_bytes() == b"\x00\x01"


def test_the_three_writers_use_the_one_atomic_writer():
    """Mission files, telemetry recordings and learning outputs all write through typed_config.files."""
    import inspect

    import bridge.missions.files
    import learning.checkpoint
    import uav_swarm.cli.telemetry

    for module in (bridge.missions.files, learning.checkpoint, uav_swarm.cli.telemetry):
        source = inspect.getsource(module)
        assert "typed_config.files import" in source and "os.replace(" not in source, module.__name__
