"""validation.dataset_target: where a data set may be written (the rules of synth)."""

from __future__ import annotations

import pytest
import yaml

from granular_mpc.exceptions import OutputError
from granular_mpc.validation.dataset_target import DatasetTarget, dataset_target


def _dataset(folder, generator: bool):
    folder.mkdir(parents=True, exist_ok=True)
    meta = {"robot": "yobogo10s", "trials": {"a": {"file": "a.csv"}, "b": {"file": "b.csv"}}}
    if generator:
        meta["generator"] = {"scenario": "sand_walk"}
    (folder / "meta.yaml").write_text(yaml.safe_dump(meta), encoding="utf-8")
    for name in ("a.csv", "b.csv", "notes.txt"):
        (folder / name).write_text("x\n", encoding="utf-8")
    return folder


def test_new_or_empty_folders_are_fine(tmp_path):
    assert dataset_target(tmp_path / "new") == []
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / ".hidden").write_text("", encoding="utf-8")
    assert dataset_target(tmp_path / "empty") == []


def test_measured_data_is_never_replaced_not_even_with_overwrite(tmp_path):
    folder = _dataset(tmp_path / "lab", generator=False)
    for overwrite in (False, True):
        with pytest.raises(OutputError, match="measured data"):
            dataset_target(folder, overwrite)
    assert sorted(p.name for p in folder.iterdir()) == ["a.csv", "b.csv", "meta.yaml",
                                                        "notes.txt"]


def test_a_synthetic_data_set_is_replaced_only_with_overwrite_and_only_its_files(tmp_path):
    folder = _dataset(tmp_path / "synth", generator=True)
    with pytest.raises(OutputError, match="--overwrite"):
        dataset_target(folder)
    files = dataset_target(folder, overwrite=True)
    assert sorted(p.name for p in files) == ["a.csv", "b.csv", "meta.yaml"]   # not notes.txt


def test_a_foreign_folder_or_a_file_is_refused(tmp_path):
    (tmp_path / "foreign").mkdir()
    (tmp_path / "foreign" / "thesis.tex").write_text("x", encoding="utf-8")
    with pytest.raises(OutputError, match="thesis.tex"):
        dataset_target(tmp_path / "foreign", overwrite=True)
    (tmp_path / "plain").write_text("x", encoding="utf-8")
    with pytest.raises(OutputError, match="not a folder"):
        dataset_target(tmp_path / "plain")


def test_an_unreadable_meta_file_is_treated_as_measured_data(tmp_path):
    folder = tmp_path / "broken"
    folder.mkdir()
    (folder / "meta.yaml").write_bytes(b"\xff\xfe: [")
    with pytest.raises(OutputError, match="cannot be read"):
        dataset_target(folder, overwrite=True)


def test_the_target_removes_a_folder_it_created_if_nothing_was_written(tmp_path):
    folder = tmp_path / "fresh"
    with DatasetTarget(folder, overwrite=False):
        assert folder.is_dir()
    assert not folder.exists()
