"""Merging data sets (validation/dataformat/merge.py, ``granular-mpc merge``): the trials of
separate recordings of one experiment in one data set, renamed only where names clash;
recordings of different experiments refused with one error naming both."""

from __future__ import annotations

import pandas as pd
import pytest

from granular_mpc.exceptions import ConfigError, OutputError
from granular_mpc.validation.dataformat import load_dataset, write_dataset
from granular_mpc.validation.dataformat.drop import drop_channels
from granular_mpc.validation.dataformat.merge import merge_datasets


@pytest.fixture(scope="module")
def parts(workbench_data, tmp_path_factory):
    """The null workbench set (3 trials) split into two data sets, as two imports would
    give them: ``first`` (trials 1–2) and ``second`` (trial 3); ``again`` holds trial 1
    once more (a name that clashes)."""
    full = load_dataset(workbench_data("null"))
    names = list(full.trials)
    root = tmp_path_factory.mktemp("merge")

    def part(folder, keep, **meta):
        m = full.meta.model_copy(update={"trials": {n: full.meta.trials[n] for n in keep},
                                         **meta})
        return write_dataset(root / folder, m, {n: full.trials[n] for n in keep}, "parquet")

    return {"full": full, "names": names, "root": root,
            "first": part("first", names[:2]), "second": part("second", names[2:]),
            "again": part("again", names[:1]),
            "other_ground": part("other_ground", names[2:], terrain="wet sand"),
            "other_hold": part("other_hold", names[2:], torque_hold_s=0.001)}


def test_merged_trials_are_the_sources_trials(parts, tmp_path):
    out = merge_datasets([parts["first"], parts["second"]], tmp_path / "m")
    ds, full = load_dataset(out), parts["full"]
    assert list(ds.trials) == parts["names"]
    for n in parts["names"]:
        pd.testing.assert_frame_equal(ds.trials[n], full.trials[n])
        assert ds.commanded_speed(n) == full.commanded_speed(n)
    assert ds.meta.robot == full.meta.robot and ds.meta.sample_rate_hz == full.meta.sample_rate_hz
    assert str(parts["first"]) in ds.meta.description
    assert ds.meta.generator == full.meta.generator           # the same synthetic record
    assert ds.meta.torque_hold_s == full.meta.torque_hold_s == 0.002


def test_clashing_trial_names_take_their_source_folder(parts, tmp_path):
    n1 = parts["names"][0]
    ds = load_dataset(merge_datasets([parts["first"], parts["again"]], tmp_path / "m"))
    assert f"first_{n1}" in ds.trials and f"again_{n1}" in ds.trials
    assert parts["names"][1] in ds.trials                      # no clash: name kept
    pd.testing.assert_frame_equal(ds.trials[f"again_{n1}"], parts["full"].trials[n1])
    assert f"{n1} → again_{n1}" in ds.meta.description


def test_other_experiments_are_refused_naming_both(parts, tmp_path):
    with pytest.raises(ConfigError, match="wet sand") as exc:
        merge_datasets([parts["first"], parts["other_ground"]], tmp_path / "m")
    assert exc.value.key == "terrain" and str(parts["other_ground"]) in str(exc.value)
    # the user names the merged ground: accepted
    ds = load_dataset(merge_datasets([parts["first"], parts["other_ground"]], tmp_path / "m2",
                                     terrain="dry and wet sand"))
    assert ds.meta.terrain == "dry and wet sand" and len(ds.trials) == 3
    fewer = drop_channels(parts["second"], tmp_path / "fewer", ["intrusion"])
    with pytest.raises(ConfigError, match="channels") as exc:
        merge_datasets([parts["first"], fewer], tmp_path / "m3")
    assert exc.value.key == "channels"
    # torques held for another time (another controller rate): another experiment
    with pytest.raises(ConfigError, match="torque_hold_s") as exc:
        merge_datasets([parts["first"], parts["other_hold"]], tmp_path / "m4")
    assert exc.value.key == "torque_hold_s"


def test_bad_calls_get_one_clear_error(parts, tmp_path):
    with pytest.raises(ConfigError, match="at least two"):
        merge_datasets([parts["first"]], tmp_path / "m")
    with pytest.raises(ConfigError, match="more than once"):
        merge_datasets([parts["first"], parts["first"]], tmp_path / "m")
    with pytest.raises(ConfigError, match="output folder is one of the sources"):
        merge_datasets([parts["first"], parts["second"]], parts["second"])
    out = merge_datasets([parts["first"], parts["second"]], tmp_path / "m")
    before = (out / "meta.yaml").read_bytes()
    with pytest.raises(OutputError):
        merge_datasets([parts["first"], parts["again"]], out)
    assert (out / "meta.yaml").read_bytes() == before           # nothing overwritten


def test_cli_merge(parts, tmp_path):
    from typer.testing import CliRunner

    from granular_mpc.cli import app

    res = CliRunner().invoke(app, ["merge", str(parts["first"]), str(parts["second"]),
                                   "--out", str(tmp_path / "cli")])
    assert res.exit_code == 0, res.output
    assert "3 trial(s)" in res.output
    bad = CliRunner().invoke(app, ["merge", str(parts["first"]), "--out", str(tmp_path / "b")])
    assert bad.exit_code == 2 and "at least two" in bad.output
