"""validation.dataformat.checks_stance: stance labels checked against the foot kinematics."""

from __future__ import annotations

import numpy as np
import pytest

from granular_mpc.columns import STANCE
from granular_mpc.exceptions import DataFormatError
from granular_mpc.validation import load_dataset, write_dataset
from granular_mpc.validation.dataformat.checks_stance import MAX_AGREEMENT, MIN_SWAPPED


@pytest.fixture(scope="module")
def walk(workbench_data):
    """A simulated walk on sand (the workbench's null data set, noise-free)."""
    return load_dataset(workbench_data("null", noisy=False))


def _write(tmp_path, walk, edit):
    trials = {n: edit(df.copy()) for n, df in walk.trials.items()}
    out = tmp_path / "ds"
    write_dataset(out, walk.meta.model_dump(mode="json"), trials, "parquet", check=False)
    return out


def test_walking_labels_pass_the_side_check(tmp_path, walk):
    assert MAX_AGREEMENT < 0.5 < MIN_SWAPPED
    ds = load_dataset(_write(tmp_path, walk, lambda df: df))
    assert set(ds.trials) == set(walk.trials)


def test_swapped_labels_are_reported_naming_file_and_column(tmp_path, walk):
    def swap(df):
        lab = df[STANCE].to_numpy(dtype=object)
        df[STANCE] = np.where(lab == "left", "right", np.where(lab == "right", "left", lab))
        return df

    with pytest.raises(DataFormatError) as err:
        load_dataset(_write(tmp_path, walk, swap))
    problems = [p for p in err.value.problems if "swapped" in p.message]
    assert len(problems) == len(walk.trials)
    assert all(p.column == STANCE and p.file.endswith(".parquet") for p in problems)
