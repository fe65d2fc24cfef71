"""granular_mpc.output: checked output folders, JSON-safe values, atomic JSON files."""
from __future__ import annotations

import json
import math
import threading

import numpy as np
import pytest

from granular_mpc.exceptions import OutputError
from granular_mpc.output import exclusive_lock, json_safe, make_output_folder, write_json


def test_json_safe_turns_numpy_and_non_finite_values_into_json():
    value = {1: np.float64(math.nan), "a": [np.int64(3), np.bool_(True), (np.inf, 2.5)],
             "arr": np.array([[1.0, np.nan]])}
    safe = json_safe(value)
    assert safe == {"1": None, "a": [3, True, [None, 2.5]], "arr": [[1.0, None]]}
    assert json.loads(json.dumps(safe, allow_nan=False)) == safe
    assert type(safe["a"][0]) is int and type(safe["a"][1]) is bool


def test_make_output_folder_creates_parents_and_rejects_a_file(tmp_path):
    out = make_output_folder(tmp_path / "x" / "y")
    assert out.is_dir() and list(out.iterdir()) == []      # the write probe is removed
    blocker = tmp_path / "file"
    blocker.write_text("keep me")
    with pytest.raises(OutputError, match="exists and is not a folder"):
        make_output_folder(blocker)
    assert blocker.read_text() == "keep me"


def test_write_json_is_strict_and_leaves_no_temporary_file(tmp_path):
    path = write_json(tmp_path / "s.json", {"a": 1, "b": [None, 2.5]})
    assert json.loads(path.read_text()) == {"a": 1, "b": [None, 2.5]}
    assert path.read_text().endswith("\n") and sorted(p.name for p in tmp_path.iterdir()) == ["s.json"]
    with pytest.raises(ValueError):
        write_json(tmp_path / "s.json", {"a": math.nan})
    assert json.loads(path.read_text()) == {"a": 1, "b": [None, 2.5]}   # old file kept


def test_write_json_into_a_missing_folder_is_an_output_error(tmp_path):
    with pytest.raises(OutputError, match="cannot write"):
        write_json(tmp_path / "missing" / "s.json", {})


def test_exclusive_lock_makes_a_second_holder_wait(tmp_path):
    """A second ``exclusive_lock`` on the same file (here from a thread: ``flock`` locks
    conflict between open file descriptions) gets it only after the first is released."""
    lock = tmp_path / "x.lock"
    events: list[str] = []

    def second():
        with exclusive_lock(lock):
            events.append("second holds")

    with exclusive_lock(lock):
        t = threading.Thread(target=second)
        t.start()
        t.join(timeout=0.3)
        assert t.is_alive() and events == []        # waiting, not holding
        events.append("first releases")
    t.join(timeout=5)
    assert events == ["first releases", "second holds"]
