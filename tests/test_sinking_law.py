"""An added terrain force whose own law fits the sinking-sample force worse than a single
law of the proposal (``validation.diagnosis.sinking_law``): the comparison against the
proposal's record on a real data set, which added effects it judges, and the verdict it
changes."""

from __future__ import annotations

import pytest

from granular_mpc.validation.diagnosis import ParamEstimate, Ranked
from granular_mpc.validation.diagnosis.acceptance_records import LawPreferred
from granular_mpc.validation.diagnosis.candidates import build_candidates
from granular_mpc.validation.diagnosis.force_start import fit_start
from granular_mpc.validation.diagnosis.localization_records import Localization
from granular_mpc.validation.diagnosis.proposal_records import AxisFit, Proposal, ProposedTerm
from granular_mpc.validation.diagnosis.sample_forces import equation_states
from granular_mpc.validation.diagnosis.sinking_law import LAW_SHARE, law_preferred
from granular_mpc.validation.diagnosis.verdict import VerdictInputs, best_candidate_statement

THETA = {"zeta": 1.36}


def _proposal(law_rms_after: float, rms_before: float, stage: str = "layer") -> Proposal:
    """A proposal whose vertical axis passed with one layer law explaining
    √(before² − after²)."""
    term = ProposedTerm("z", "law_below_15mm", "", 0.6, 0.6, 0.03, "-", 1.0, True)
    axis = AxisFit("z", 0.5, 0.5, rms_before, law_rms_after, 1.0, True, stage)
    return Proposal("proposed_force", "proposed_effect.py", (term,), (axis,), 300, 21)


def test_an_added_law_that_explains_less_than_the_proposals_law_is_named(workbench_data):
    """On the null workbench data set, depth hardening fitted on the sinking samples (its
    n searched, ζ free) explains some newton; a proposal record whose layer law explains
    twice that names it (with both forces), one whose law explains no more than it does
    not; the library-stage fit (more flexible than any one term) is never compared."""
    from granular_mpc.validation.diagnosis.problem import load_problem

    problem = load_problem(workbench_data("null"))
    cands = build_candidates(["depth_hardening", "cohesion"])
    fs, states = equation_states(problem, THETA)
    own = fit_start("depth_hardening", cands, states, fs, THETA["zeta"], axes=("z",))
    before = own.rms_before
    assert 0.0 < own.explained < before

    def law_with(explained):                # rms_after so that √(before² − after²) = explained
        return _proposal((before ** 2 - explained ** 2) ** 0.5, before)

    got = law_preferred(problem, cands, THETA, ["depth_hardening"], law_with(2.0 * own.explained))
    assert len(got) == 1 and got[0].effect == "depth_hardening" and got[0].axis == "z"
    assert got[0].term_explained == pytest.approx(own.explained, rel=1e-9)
    assert got[0].law_explained == pytest.approx(2.0 * own.explained, rel=1e-6)
    assert got[0].law == ("law_below_15mm",)
    assert law_preferred(problem, cands, THETA, ["depth_hardening"],
                         law_with(own.explained / LAW_SHARE * 0.99)) == ()
    library_stage = _proposal(0.1 * before, before, stage="library")
    assert law_preferred(problem, cands, THETA, ["depth_hardening"], library_stage) == ()
    # cohesion acts only while the sole rises: no force on these samples, not judged here
    assert law_preferred(problem, cands, THETA, ["cohesion"], law_with(5.0)) == ()
    assert law_preferred(problem, cands, THETA, ["depth_hardening"], None) == ()


def test_a_better_simple_law_makes_the_added_term_only_the_closest_proxy():
    """The same addition, with and without a LawPreferred record: the answer becomes the
    closest proxy, and the statement names the law and both forces."""
    est = ParamEstimate(1.3, 0.01, 1.28, 1.32, "-", 1.0, 0.3, 3.0, False, 1.28, 1.32)
    r = Ranked(effect="depth_hardening", kind="terrain_force", heldout_error_reduction=0.3,
               heldout_error_reduction_stance=0.2, delta_aicc=-50.0, folds_improved="3/3",
               effect_size=3.0, params={"n": est}, main="n", depends_on=(), doc="",
               inclusion_probability=1.0, significant=True, rank=1, added=True,
               refined_params={"n": 1.3})
    empty = Localization((), (), 0, 0, {}, (), {}, {})
    v = VerdictInputs(("depth_hardening",), (r,), None, empty, empty)
    assert best_candidate_statement(v).startswith("depth_hardening is the answer")
    lp = LawPreferred("depth_hardening", "z", 4.6, ("law_below_15mm",), 6.2, LAW_SHARE)
    v2 = VerdictInputs(("depth_hardening",), (r,), None, empty, empty, law_preferred=(lp,))
    text = best_candidate_statement(v2)
    assert text.startswith("depth_hardening is only the closest proxy")
    assert "law_below_15mm" in text and "6.2 N" in text and "4.6 N" in text and "74 %" in text
    assert LawPreferred.from_dict(lp.to_dict()) == lp              # diagnosis.json round trip
