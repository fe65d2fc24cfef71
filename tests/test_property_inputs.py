"""Property tests (Hypothesis): the config loader and the data-set loader on mutated
inputs. Every outcome is a loaded object or one of the package's errors
(GranularMpcError subclasses) — never another exception."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from granular_mpc.exceptions import GranularMpcError
from granular_mpc.scenario import load_scenario
from granular_mpc.validation import load_dataset
from granular_mpc.validation.dataformat import write_dataset

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = (ROOT / "sim" / "rigid_walk.yaml").read_bytes()
SETTINGS = settings(max_examples=60, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture,
                                           HealthCheck.too_slow])


def _mutate(data: bytes, edits: list[tuple[int, int, bytes]]) -> bytes:
    """Apply (position, length to delete, bytes to insert) edits."""
    b = bytearray(data)
    for pos, n, ins in edits:
        p = pos % (len(b) + 1)
        b[p:p + n] = ins
    return bytes(b)


TEXT_BITS = [b"", b":", b" ", b"\n", b"-", b"  x: 1\n", b"[", b"{", b"'", b"0", b"1e999",
             b"nan", b"\t", b"duration: 5\n", b"&a", b"*a", b"!!python/none", b",", b"\x00"]


def _edits(bits: list[bytes]):
    return st.lists(st.tuples(st.integers(0, 10_000), st.integers(0, 8), st.sampled_from(bits)),
                    min_size=1, max_size=4)


EDITS = _edits(TEXT_BITS + [b"\xff\xfe"])     # with bytes that are not UTF-8
TEXT_EDITS = _edits(TEXT_BITS)


@SETTINGS
@given(edits=EDITS)
def test_config_loader_on_mutated_scenarios(tmp_path_factory, edits):
    path = tmp_path_factory.mktemp("cfg") / "scenario.yaml"
    path.write_bytes(_mutate(SCENARIO, edits))
    try:
        load_scenario(str(path))
    except GranularMpcError:
        pass


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory, workbench_data):
    """A tiny CSV data set (one trial, a few hundred rows) to mutate."""
    ds = load_dataset(workbench_data("null", noisy=False))
    name = sorted(ds.trials)[0]
    trial = ds.trials[name].iloc[:400].reset_index(drop=True)
    meta = ds.meta.model_dump(mode="json")
    meta["trials"] = {name: meta["trials"][name]}
    out = tmp_path_factory.mktemp("ds") / "base"
    write_dataset(out, meta, {name: trial}, "csv", check=False)
    return out


@SETTINGS
@given(target=st.sampled_from(["meta", "trial"]), edits=TEXT_EDITS)
def test_data_loader_on_mutated_data_sets(small_dataset, tmp_path_factory, target, edits):
    folder = tmp_path_factory.mktemp("mut") / "ds"
    shutil.copytree(small_dataset, folder)
    file = folder / "meta.yaml" if target == "meta" else next(folder.glob("*.csv"))
    file.write_bytes(_mutate(file.read_bytes(), edits))
    try:
        load_dataset(folder)
    except GranularMpcError:
        pass


@pytest.mark.parametrize("target", ["meta", "trial"])
def test_data_loader_names_a_file_that_is_not_utf8(small_dataset, tmp_path, target):
    folder = tmp_path / "ds"
    shutil.copytree(small_dataset, folder)
    file = folder / "meta.yaml" if target == "meta" else next(folder.glob("*.csv"))
    file.write_bytes(b"\xff\xfe" + file.read_bytes())
    with pytest.raises(GranularMpcError, match=file.name):
        load_dataset(folder)
