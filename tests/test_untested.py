"""What a diagnosis did not test (validation/diagnosis/untested.py): a verdict that is not a
clean answer names the opt-in candidate families that were not among the candidates, and
the option that adds them; ``diagnose --variants`` adds the per-foot and layered ones."""

from __future__ import annotations

import json
from types import SimpleNamespace

from granular_mpc.validation.diagnosis.result import Verdict
from granular_mpc.validation.diagnosis.untested import (OPT_IN_FAMILIES, untested_families,
                                                        untested_sentence, with_untested)


def _infos(*tag_sets):
    return {f"e{i}": SimpleNamespace(tags=tuple(t)) for i, t in enumerate(tag_sets)}


def test_the_family_tags_are_the_effect_modules_tags():
    from granular_mpc.effects.measurement import TAG
    from granular_mpc.effects.variants import LAYERED_TAG, PER_FOOT_TAG

    assert [f[0] for f in OPT_IN_FAMILIES] == [(TAG,), (PER_FOOT_TAG, LAYERED_TAG)]


def test_families_without_a_candidate_are_named():
    assert len(untested_families([(), ()])) == 2
    only_meas = untested_families([("measurement",), ()])
    assert len(only_meas) == 1 and "--variants" in only_meas[0]
    assert untested_families([("measurement",), ("layered",)]) == ()
    assert untested_sentence(_infos(("measurement",), ("per_foot",))) == ""
    assert "--measurement" in untested_sentence(_infos(("per_foot",)))


def test_only_a_verdict_that_is_not_a_clean_answer_gets_the_sentence():
    infos = _infos(())
    for status in ("unexplained_structure", "partially_explained"):
        v = with_untested(Verdict(status, "text", ()), "", infos)
        assert v.text.startswith("text. Not among the candidates: the measurement model")
        assert "--variants" in v.text and v.status == status
    answer = Verdict("missing_effect", "text", ("cohesion",))
    assert with_untested(answer, "cohesion is the answer", infos) == answer
    proxy = with_untested(answer, "cohesion is only the closest proxy: …", infos)
    assert "--measurement" in proxy.text
    none = Verdict("no_significant_missing_effect", "text", ())
    assert with_untested(none, "", infos) == none


def test_cli_variants_are_candidates_and_the_verdict_names_what_was_not(workbench_data,
                                                                        tmp_path):
    """``--variants`` registers the per-foot variants: ``stress_scale_right`` is ranked. On
    the "unknown" data (a sideways push no candidate has) the verdict is not an answer and
    names the measurement model as untested, not the variants."""
    from typer.testing import CliRunner

    from granular_mpc.cli import app

    out = tmp_path / "diag"
    res = CliRunner().invoke(app, ["diagnose", str(workbench_data("unknown")), "--out",
                                   str(out), "--variants", "--candidate", "stress_scale_right",
                                   "--candidate", "cohesion", "--workers", "1"])
    assert res.exit_code == 0, res.output
    d = json.loads((out / "diagnosis.json").read_text())
    assert "stress_scale_right" in [r["effect"] for r in d["ranking"]]
    text = d["verdict"]["text"]
    assert d["verdict"]["status"] in ("unexplained_structure", "partially_explained"), text
    assert "Not among the candidates: the measurement model" in text
    assert "--variants" not in text
