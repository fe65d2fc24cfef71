"""The refinement's contender rule (``diagnosis.refine.contenders_for``): the screening's
indistinguishable partner of the leading candidate is refined by replays even when it is
not significant, and nothing is refined without a significant leader; a rejection or an
acceptance holds against the model it was judged on (``rejected_against``,
``rejudge_earlier``); a contest records each effect once (``one_per_effect``)."""

import numpy as np
import pytest

from granular_mpc.validation.diagnosis.acceptance_records import Acceptance
from granular_mpc.validation.diagnosis.ranking_records import CandidateStats
from granular_mpc.validation.diagnosis.refine import (contenders_for, is_rival,
                                                      one_per_effect, rejected_against)
from granular_mpc.validation.diagnosis.result import IndistinguishablePair
from granular_mpc.validation.diagnosis.screen import (MIN_SHARED_INCLUSION, inclusion_ties,
                                                      share_inclusion)
from granular_mpc.validation.diagnosis.thresholds import MAX_DELTA_AICC, MIN_INCLUSION


def _row(effect: str, reduction: float, inclusion: float, *, passes: bool = True) -> dict:
    """A screening row (the dict ``candidate_stats`` builds before its records)."""
    return dict(effect=effect, kind="terrain",
                heldout_error_reduction=reduction if passes else 0.0,
                heldout_error_reduction_stance=0.5, delta_aicc=MAX_DELTA_AICC - 10.0,
                folds_improved="3/3", effect_size=3.0, params={}, main="p", depends_on=(),
                doc="", inclusion_probability=inclusion,
                significant=passes and inclusion >= MIN_INCLUSION)


def _stats(rows: list[dict]) -> list[CandidateStats]:
    rows.sort(key=lambda r: -r["heldout_error_reduction"])
    return [CandidateStats(**r, rank=i + 1) for i, r in enumerate(rows)]


def _split_screening():
    """joint_friction and depth_hardening split the bootstrap (neither reaches
    MIN_INCLUSION alone: the screening makes the leader significant, not the partner);
    cohesion passes nothing; inertial_drag is significant on its own further down (its
    bootstrap share taken from the others' selections is not part of the split)."""
    half = MIN_INCLUSION / 2 + 0.02
    assert half >= MIN_SHARED_INCLUSION and half < MIN_INCLUSION
    rows = [_row("joint_friction", 0.40, half), _row("depth_hardening", 0.35, half),
            _row("cohesion", 0.0, 0.0, passes=False)]
    rows.sort(key=lambda r: -r["heldout_error_reduction"])
    share_inclusion(rows)
    rows.append(dict(_row("inertial_drag", 0.2, 0.9)))
    stats = _stats(rows)
    pairs = [IndistinguishablePair(p, 0.5, (0.4, 0.35), "") for p in inclusion_ties(stats)]
    return stats, pairs


def test_partner_that_is_not_significant_is_refined():
    stats, pairs = _split_screening()
    by = {r.effect: r for r in stats}
    assert by["joint_friction"].significant and not by["depth_hardening"].significant
    assert [p.effects for p in pairs] == [("joint_friction", "depth_hardening")]
    out = [r.effect for r in contenders_for(stats, [], set(), 1, pairs)]
    assert out == ["joint_friction", "depth_hardening"]
    # with room for two significant contenders the partner comes after them
    out = [r.effect for r in contenders_for(stats, [], set(), 2, pairs)]
    assert out == ["joint_friction", "inertial_drag", "depth_hardening"]
    # without the pairs: the significant candidates, then depth_hardening as a rival (it
    # passes every test but the inclusion, is_rival); cohesion passes nothing
    out = [r.effect for r in contenders_for(stats, [], set(), 2, ())]
    assert out == ["joint_friction", "inertial_drag", "depth_hardening"]


def test_partner_order_in_the_pair_does_not_matter():
    stats, pairs = _split_screening()
    flipped = [IndistinguishablePair(p.effects[::-1], p.correlation,
                                     p.heldout_error_reduction, p.experiment) for p in pairs]
    out = [r.effect for r in contenders_for(stats, [], set(), 1, flipped)]
    assert out == ["joint_friction", "depth_hardening"]


def test_only_the_leading_contenders_partner_is_added():
    stats, _ = _split_screening()
    pairs = [IndistinguishablePair(("inertial_drag", "cohesion"), 0.95, (0.2, 0.0), "")]
    out = [r.effect for r in contenders_for(stats, [], set(), 2, pairs)]
    assert out == ["joint_friction", "inertial_drag", "depth_hardening"]   # (a rival)
    assert "cohesion" not in out                  # the partner of a non-leader is not
    # once the leader is rejected, inertial drag leads and its partner is refined
    out = [r.effect for r in contenders_for(stats, [], {"joint_friction"}, 2, pairs)]
    assert out == ["inertial_drag", "cohesion", "depth_hardening"]


def test_after_an_addition_the_leaders_partner_against_the_current_model_is_the_fallback():
    """After a force-sensor bias is added, the conditional test ranks a joint proposal
    first (inclusion 0.92) and the user's knee spring, collinear with it (0.95), loses the
    bootstrap vote (0.08). With the collinear pairs measured against the current model the
    spring is the leader's partner: a contender of the same step (not a rival), so the
    acceptance judges it when the proposal is refused. Without them it is only a rival,
    which is never the fallback of a rejected leader (the out-of-library pair of seed 4,
    docs/validation.md §5.3.13)."""
    rows = [_row("proposed_joint", 0.49, 0.92), _row("user_knee_spring", 0.42, 0.08),
            _row("cohesion", 0.0, 0.0, passes=False)]
    stats = _stats(rows)
    pair = [IndistinguishablePair(("proposed_joint", "user_knee_spring"), 0.95, (0.49, 0.42),
                                  "")]
    selected = ["force_sensor_bias"]
    assert [r.effect for r in contenders_for(stats, selected, set(), 2, pair,
                                             with_rivals=False)] == ["proposed_joint",
                                                                     "user_knee_spring"]
    spring = stats[1]
    assert spring.effect == "user_knee_spring" and not spring.significant and is_rival(spring)
    assert [r.effect for r in contenders_for(stats, selected, set(), 2, (),
                                             with_rivals=False)] == ["proposed_joint"]
    assert [r.effect for r in contenders_for(stats, selected, set(), 2, ())] == [
        "proposed_joint", "user_knee_spring"]                 # as a rival only
    # a partner is refined only beside a significant leader
    assert contenders_for(stats, selected, {"proposed_joint"}, 2, pair) == []


def test_nothing_is_refined_without_a_significant_leader():
    rows = [_row("joint_friction", 0.40, 0.3), _row("depth_hardening", 0.35, 0.1)]
    stats = _stats(rows)
    assert not any(r.significant for r in stats)
    pairs = [IndistinguishablePair(("joint_friction", "depth_hardening"), 0.95, (0.4, 0.35),
                                   "")]
    assert contenders_for(stats, [], set(), 2, pairs) == []


def test_added_or_rejected_partners_are_not_refined_again():
    stats, pairs = _split_screening()
    out = [r.effect for r in contenders_for(stats, [], {"depth_hardening"}, 1, pairs)]
    assert out == ["joint_friction"]
    out = [r.effect for r in contenders_for(stats, ["depth_hardening"], set(), 1, pairs)]
    assert out == ["joint_friction"]


def test_the_acceptance_baseline_is_the_refined_model_without_the_new_term():
    """``without_term`` replays the co-refitted calibration θ and the earlier effects at
    their refined values, the newest term left out (its own replays are what it is judged
    on, not the calibration's shift)."""
    from types import SimpleNamespace

    from granular_mpc.effects import effect_info
    from granular_mpc.validation.diagnosis.refine import without_term

    seen = {}

    class Pool:
        def run(self, variants):
            seen.update(variants)
            return {k: [{"grf_z": [1.0]}] for k in variants}

    names = ("cohesion", "joint_friction", "force_sensor_bias")
    cands = SimpleNamespace(infos={n: effect_info(n) for n in names})
    res = SimpleNamespace(base=SimpleNamespace(theta={"zeta": 1.0, "phi_s": 0.6}))
    fit = SimpleNamespace(theta={"zeta": 1.4},
                          fitted={"cohesion": {"suction": 1500.0},
                                  "joint_friction": {"coulomb": 0.1, "viscous": 0.0,
                                                     "smoothing": 0.2},
                                  "force_sensor_bias": {"bias_z": 6.0}})
    out = without_term(Pool(), res, cands, fit, ["cohesion", "joint_friction"])
    assert out == ({"grf_z": [1.0]},)
    (v,) = seen.values()
    assert v.theta["zeta"] == 1.4 and v.theta["phi_s"] == 0.6
    assert v.theta["cohesion.suction"] == 1500.0
    assert [i.name for i, _ in v.joints] == ["joint_friction"]
    assert v.sensors == ()                 # the newest term (the sensor bias) is left out
    # nothing added before: the co-refitted θ alone
    without_term(Pool(), res, cands, fit, [])
    (v,) = seen.values()
    assert v.joints == () and v.sensors == () and "cohesion.suction" not in v.theta


def test_a_rival_that_lost_only_the_bootstrap_vote_is_refined():
    """A candidate passing every test but the inclusion (the linear bootstrap voted for
    another) is refined beside the leader; one failing another test, a strength twin, or
    any candidate when nothing is significant is not."""
    rows = [_row("joint_friction", 0.57, 1.0), _row("user_stiction", 0.53, 0.38),
            _row("elastic_unloading", 0.10, 0.62, passes=False),
            _row("cohesion", 0.30, 0.0)]
    stats = _stats(rows)
    by = {r.effect: r for r in stats}
    assert is_rival(by["user_stiction"]) and not is_rival(by["joint_friction"])
    assert not is_rival(by["elastic_unloading"])
    out = [r.effect for r in contenders_for(stats, [], set(), 1)]
    assert out == ["joint_friction", "user_stiction"]          # at most 1 rival here
    out = [r.effect for r in contenders_for(stats, [], set(), 2)]
    assert out == ["joint_friction", "user_stiction", "cohesion"]
    out = [r.effect for r in contenders_for(stats, [], set(), 2, (), {"user_stiction"})]
    assert out == ["joint_friction", "cohesion"]                # a twin is no rival
    # a rival fails the held-out test: not refined
    weak = _stats([_row("joint_friction", 0.57, 1.0), _row("user_stiction", 0.01, 0.38)])
    assert [r.effect for r in contenders_for(weak, [], set(), 2)] == ["joint_friction"]
    # nothing significant: nothing refined, rivals included
    none = _stats([_row("user_stiction", 0.53, 0.38), _row("cohesion", 0.30, 0.1)])
    assert contenders_for(none, [], set(), 2) == []


def test_a_rival_is_judged_only_when_it_beats_the_others():
    """A rival is no fallback: judged only when its refined AICc is the lowest."""
    from granular_mpc.validation.diagnosis.refine import judging_order

    scored = [(337.9, "user_knee_spring"), (487.9, "joint_friction"), (499.3, "inertial_drag")]
    assert judging_order(scored, {"inertial_drag"}) == ["user_knee_spring", "joint_friction"]
    scored = [(420.0, "joint_friction"), (380.0, "user_stiction")]
    assert judging_order(scored, {"user_stiction"}) == ["user_stiction", "joint_friction"]
    assert judging_order(scored, set()) == ["user_stiction", "joint_friction"]


def _judged(effect: str, accepted: bool, given: tuple[str, ...] = ()) -> Acceptance:
    return Acceptance(effect, accepted, {}, (), () if accepted else ("worse",), (), given)


def test_a_rejection_holds_only_against_the_model_it_was_judged_on():
    """A knee spring rejected while a force-sensor bias was unmodelled is a contender again
    once the bias is added; rejected again against that model, it is blocked for it."""
    stats, _ = _split_screening()        # joint_friction leads, inertial_drag significant
    first = [_judged("joint_friction", False)]
    assert rejected_against(first, []) == {"joint_friction"}
    assert [r.effect for r in contenders_for(stats, [], rejected_against(first, []), 3,
                                             with_rivals=False)] == ["inertial_drag"]
    after = first + [_judged("inertial_drag", True)]
    assert rejected_against(after, ["inertial_drag"]) == set()
    again = contenders_for(stats, ["inertial_drag"], rejected_against(after, ["inertial_drag"]),
                           3, with_rivals=False)
    assert [r.effect for r in again] == ["joint_friction"]
    twice = after + [_judged("joint_friction", False, ("inertial_drag",))]
    assert rejected_against(twice, ["inertial_drag"]) == {"joint_friction"}
    assert contenders_for(stats, ["inertial_drag"],
                          rejected_against(twice, ["inertial_drag"]), 3, with_rivals=False) == []


class _Pool:
    """Replays of the fake model: a joint effect in the variant explains the knees, a sensor
    effect ``grf_z`` — as ``truth`` says (the effects' names whose own replays help)."""

    def __init__(self, windows, truth):
        self.windows, self.truth, self.calls = windows, truth, 0

    def preds(self, effects):
        out = []
        for w in self.windows:
            p = {c: np.array(v, float) for c, v in w.meas.items()}
            for c, name in (("q_left_knee", "joint_friction"), ("grf_z", "force_sensor_bias")):
                helps = name in effects and name in self.truth
                hurts = name in effects and name not in self.truth
                miss = 0.0 if helps else (0.02 if c == "q_left_knee" else 2.0)
                p[c] = p[c] + miss * (1.0 + 0.1 * w.index) * (1.5 if hurts else 1.0)
            out.append(p)
        return out

    def run(self, variants):
        self.calls += 1
        return {k: self.preds({i.name for i, _ in (*v.joints, *v.sensors)})
                for k, v in variants.items()}


def _windows():
    """Six fake stance windows with a knee angle and a vertical force."""
    from types import SimpleNamespace

    rng = np.random.default_rng(0)
    return [SimpleNamespace(index=i, meas={"q_left_knee": rng.normal(0, 1e-3, 30),
                                           "grf_z": rng.normal(50, 1, 30)})
            for i in range(6)]


def _fake_refits(monkeypatch, pool, fitted) -> list:
    """Replace the replay refit by the fake pool's predictions at ``fitted``; returns the
    list of refitted selections."""
    from types import SimpleNamespace

    import granular_mpc.validation.diagnosis.refine as refine_module

    refits = []

    def refit(problem, pool_, res, candidates, sel, start, nuisance, *, iterations):
        refits.append(tuple(sel))
        return SimpleNamespace(fitted={s: fitted[s] for s in sel}, theta={},
                               preds=pool.preds(set(sel)), log=())

    monkeypatch.setattr(refine_module, "refine_replays", refit)
    return refits


def _rejudge_case(truth, monkeypatch):
    from types import SimpleNamespace

    from granular_mpc.effects import effect_info
    from granular_mpc.validation.diagnosis.refine import rejudge_earlier

    windows = _windows()
    pool = _Pool(windows, truth)
    infos = {n: effect_info(n) for n in ("force_sensor_bias", "joint_friction")}
    fitted = {"force_sensor_bias": infos["force_sensor_bias"].resolve_params({"bias_z": 3.0}),
              "joint_friction": infos["joint_friction"].resolve_params({"coulomb": 0.1})}
    refits = _fake_refits(monkeypatch, pool, fitted)
    problem = SimpleNamespace(windows=windows, channels=["q_left_knee", "grf_z"],
                              joint_rows=None)      # no joint torques: the rule does not apply
    res = SimpleNamespace(base=SimpleNamespace(theta={}),
                          sigma={"q_left_knee": 1e-3, "grf_z": 1.0})
    selected = ["force_sensor_bias", "joint_friction"]
    acceptance = []
    kept, fit, _, preds, refit_out = rejudge_earlier(problem, pool, res,
                                          SimpleNamespace(infos=infos,
                                                          columns={n: () for n in infos}),
                                          selected, fitted, {}, pool.preds(set(selected)),
                                          acceptance, 2)
    assert (refit_out is None) == (refits == [])
    return kept, acceptance, refits


def test_an_earlier_addition_that_the_final_model_does_not_need_is_dropped(monkeypatch):
    """A force-sensor bias added first as a proxy, then the joint friction: against the final
    model its own replays make grf_z worse — dropped, the rest refitted without it; the
    same bias when it is real stays."""
    kept, acceptance, refits = _rejudge_case({"joint_friction"}, monkeypatch)
    assert kept == ["joint_friction"] and refits == [("joint_friction",)]
    (acc,) = acceptance
    assert acc.effect == "force_sensor_bias" and not acc.accepted
    assert acc.given == ("joint_friction",)
    assert acc.dropped and acc.reasons[0].startswith("its replays make the channels")

    kept, acceptance, refits = _rejudge_case({"joint_friction", "force_sensor_bias"},
                                             monkeypatch)
    assert kept == ["force_sensor_bias", "joint_friction"] and refits == []
    assert [(a.accepted, a.dropped) for a in acceptance] == [(True, False)]


class _ExchangePool:
    """Replays of a fake model with two channels: ``q_left_knee`` is explained fully by
    ``knee`` (the true term), half by ``proxy``; ``grf_z`` by ``force_sensor_bias``, which
    hurts it when ``bias_hurts_with`` is in the model too."""

    def __init__(self, windows, knee, proxy, bias_hurts_with=""):
        self.windows, self.knee, self.proxy = windows, knee, proxy
        self.bias_hurts_with = bias_hurts_with

    def preds(self, effects):
        out = []
        for w in self.windows:
            p = {c: np.array(v, float) for c, v in w.meas.items()}
            miss = 0.0 if self.knee in effects else (0.01 if self.proxy in effects else 0.02)
            p["q_left_knee"] = p["q_left_knee"] + miss * (1.0 + 0.1 * w.index)
            bias = "force_sensor_bias" in effects
            hurt = bias and self.bias_hurts_with in effects
            p["grf_z"] = p["grf_z"] + (3.0 if hurt else 0.0 if bias else 2.0)
            out.append(p)
        return out

    def run(self, variants):
        return {k: self.preds({i.name for i, _ in (*v.joints, *v.sensors)}
                              | {t.split(".")[0] for t in v.theta if "." in t})
                for k, v in variants.items()}


def _exchange_case(knee, proxy, monkeypatch, bias_hurts_with=""):
    """joint_friction (added first) and force_sensor_bias are the model; cohesion lost to
    joint_friction when joint_friction was added. ``knee``: the effect that explains
    q_left_knee fully, ``proxy``: half."""
    from types import SimpleNamespace

    import granular_mpc.validation.diagnosis.refine as refine_module
    from granular_mpc.effects import effect_info
    from granular_mpc.validation.diagnosis.refine import exchange_terms

    windows = _windows()
    pool = _ExchangePool(windows, knee, proxy, bias_hurts_with)
    names = ("joint_friction", "force_sensor_bias", "cohesion")
    infos = {n: effect_info(n) for n in names}
    fitted = {"joint_friction": infos["joint_friction"].resolve_params({"coulomb": 0.1}),
              "force_sensor_bias": infos["force_sensor_bias"].resolve_params({"bias_z": 3.0}),
              "cohesion": infos["cohesion"].resolve_params({"suction": 2000.0})}
    refits = _fake_refits(monkeypatch, pool, fitted)
    def rss(problem, candidates, res, scr, preds, fitted_, sel):
        """A stand-in AICc: the residual sum of squares over σ, + 2 per term."""
        y = sum(float(np.sum(((p[c] - w.meas[c]) / res.sigma[c]) ** 2))
                for w, p in zip(windows, preds) for c in ("q_left_knee", "grf_z"))
        return y + 2.0 * len(sel), y

    monkeypatch.setattr(refine_module, "refined_aicc", rss)
    problem = SimpleNamespace(windows=windows, channels=["q_left_knee", "grf_z"],
                              joint_rows=None)      # no joint torques: the rule does not apply
    res = SimpleNamespace(base=SimpleNamespace(theta={}),
                          sigma={"q_left_knee": 1e-3, "grf_z": 1.0})
    cands = SimpleNamespace(infos=infos, columns={n: () for n in infos})
    selected = ["joint_friction", "force_sensor_bias"]
    acceptance = []
    out = exchange_terms(problem, pool, res, None, cands, selected, fitted, {},
                         pool.preds(set(selected)),
                         {"joint_friction": [("cohesion", fitted["cohesion"])]},
                         acceptance, 2)
    return out, acceptance, refits


def test_a_proxy_added_before_the_rest_of_the_model_is_exchanged_for_the_term_it_beat(
        monkeypatch):
    """joint_friction beat cohesion when it was added; against the final model (with the
    force-sensor bias) cohesion explains the knee fully: it takes joint_friction's place,
    judged with the bias, and the bias judged again with it."""
    out, acceptance, refits = _exchange_case("cohesion", "joint_friction", monkeypatch)
    assert out is not None
    sel, fit, step, rss_new = out
    assert sel == ["cohesion", "force_sensor_bias"] and set(fit.fitted) == set(sel)
    # the RSS returned is the exchanged model's (the stand-in AICc is RSS + 2 per term)
    assert step.contender_aicc[0] == pytest.approx(rss_new + 2.0 * len(sel))
    assert step.added == "cohesion" and step.contenders == ("cohesion", "joint_friction")
    assert step.contender_aicc[0] < step.contender_aicc[1]
    assert refits == [("cohesion", "force_sensor_bias")]
    judged = {(a.effect, a.given): a for a in acceptance}
    assert judged[("cohesion", ("force_sensor_bias",))].accepted
    assert judged[("force_sensor_bias", ("cohesion",))].accepted
    gone = judged[("joint_friction", ("force_sensor_bias",))]
    assert gone.dropped and not gone.accepted
    assert gone.reasons[0].startswith("exchanged for cohesion")


def test_no_exchange_when_the_term_it_beat_fits_worse_or_breaks_another_term(monkeypatch):
    """The term joint_friction beat explains less (the AICc rises): nothing is judged, no
    exchange. It explains more but the bias, judged again beside it, makes grf_z worse: no
    exchange either (every term of the exchanged model must pass)."""
    out, acceptance, refits = _exchange_case("joint_friction", "cohesion", monkeypatch)
    assert out is None and acceptance == [] and refits == [("cohesion", "force_sensor_bias")]

    out, acceptance, _ = _exchange_case("cohesion", "joint_friction", monkeypatch,
                                        bias_hurts_with="cohesion")
    assert out is None
    bias = [a for a in acceptance if a.effect == "force_sensor_bias"]
    assert bias and not bias[0].accepted and bias[0].given == ("cohesion",)
    assert not any(a.dropped for a in acceptance)


def test_a_contest_records_each_effect_once_with_the_added_fit():
    """An effect refined from its screening estimate and from its force start has two
    refinements in a contest: the record keeps, for the added effect, the fit that passed
    the acceptance (here its higher-AICc path, the lower one having failed), for the
    others their lowest AICc; in AICc order."""
    stats = {r.effect: r for r in _stats([_row("user_term", 0.5, 0.9),
                                          _row("cohesion", 0.4, 0.9)])}
    start_path, screen_path, other, other2 = object(), object(), object(), object()
    tried = [(100.0, stats["user_term"], start_path), (120.0, stats["user_term"], screen_path),
             (110.0, stats["cohesion"], other), (130.0, stats["cohesion"], other2)]
    kept = one_per_effect(tried, screen_path)
    assert [(t[0], t[1].effect) for t in kept] == [(110.0, "cohesion"), (120.0, "user_term")]
    assert kept[1][2] is screen_path and kept[0][2] is other
    assert [t[0] for t in one_per_effect(tried, start_path)] == [100.0, 110.0]
