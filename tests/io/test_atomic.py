"""Atomic writes: complete file under the final name, or nothing at all."""

import json
import re

import pytest

from camsim.core.errors import CamsimError
from camsim.io.atomic import atomic_path, write_json_atomic, write_text_atomic


class Boom(RuntimeError):
    pass


def test_temp_path_is_hidden_sibling_and_replaced_on_success(tmp_path):
    final = tmp_path / "frame.bin"
    with atomic_path(final) as tmp:
        assert tmp.parent == final.parent
        assert tmp.name.startswith(".") and tmp != final
        tmp.write_bytes(b"complete")
        assert not final.exists()  # nothing under the final name until the block ends
    assert final.read_bytes() == b"complete"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frame.bin"]


def test_exception_mid_write_leaves_no_file(tmp_path):
    final = tmp_path / "frame.bin"
    with pytest.raises(Boom):
        with atomic_path(final) as tmp:
            with open(tmp, "wb") as fh:
                fh.write(b"half a fi")
                raise Boom("interrupted")
    assert list(tmp_path.iterdir()) == []


def test_keyboard_interrupt_mid_write_leaves_no_file(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(tmp_path / "x.json") as tmp:
            tmp.write_text("{")
            raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_failed_write_keeps_previous_complete_file(tmp_path):
    final = tmp_path / "meta.json"
    write_json_atomic(final, {"version": 1})
    before = final.read_bytes()
    with pytest.raises(Boom):
        with atomic_path(final) as tmp:
            tmp.write_text('{"version": 2, "trunc')
            raise Boom
    assert final.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["meta.json"]


def test_stale_temp_file_is_replaced(tmp_path):
    final = tmp_path / "a.txt"
    with pytest.raises(Boom):
        with atomic_path(final) as tmp:
            stale = tmp
            raise Boom
    stale.write_bytes(b"leftover from a killed process")
    with atomic_path(final) as tmp:
        assert tmp == stale and not tmp.exists()
        tmp.write_bytes(b"new")
    assert final.read_bytes() == b"new"
    assert not stale.exists()


def test_missing_directory_is_a_user_error(tmp_path):
    target = tmp_path / "no" / "such" / "dir" / "f.json"
    with pytest.raises(CamsimError, match=re.escape(str(target.parent))):
        write_json_atomic(target, {})


def test_json_exact_format_unicode_and_trailing_newline(tmp_path):
    obj = {"name": "Macbeth ColorChecker® – 24 patches", "gain": 0.1, "n": [1, 2], "nested": {"ok": True}}
    path = tmp_path / "m.json"
    write_json_atomic(path, obj)
    raw = path.read_bytes()
    assert raw == (json.dumps(obj, indent=2, ensure_ascii=False) + "\n").encode("utf-8")
    assert "ColorChecker®".encode() in raw  # not \u-escaped
    assert json.loads(raw.decode("utf-8")) == obj


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_json_refuses_nan_and_creates_nothing(tmp_path, bad):
    with pytest.raises(ValueError):
        write_json_atomic(tmp_path / "m.json", {"x": bad})
    assert list(tmp_path.iterdir()) == []


def test_text_written_verbatim_and_overwrites(tmp_path):
    path = tmp_path / "notes.txt"
    write_text_atomic(path, "first\n")
    write_text_atomic(path, "zweite Zeile: äöü\r\nno newline at end")
    assert path.read_bytes() == "zweite Zeile: äöü\r\nno newline at end".encode("utf-8")
