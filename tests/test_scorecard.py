"""The scorecard's rules (benchmarks/scorecard.py): what counts as extra confirmed, and when the
quick check calls a world lower than its baseline."""

from benchmarks import scorecard as sc


def _card(k, n, extra=0, files=None, quick=True):
    w = {"right_first": {"k": k, "n": n}, "extra_confirmed": {"k": extra, "n": n}, "errors": 0}
    if files is not None:
        w = {"files": files, "errors": 0, "right_first": {"k": sum(files.values()), "n": len(files)}}
    return {"quick": quick, "worlds": {"w": w}}


def test_the_noise_allowance_is_the_binomial_spread_at_the_full_rate():
    assert sc.allowed(3, 20, 20) == 1  # p = 21/22: ceil(1.645 sqrt(3 p (1 - p))) = 1
    assert sc.allowed(4, 6, 21) == 2
    assert sc.allowed(0, 5, 5) == 0


def test_a_drop_beyond_the_noise_fails_and_within_it_passes():
    base = {"quick": _card(4, 4), "full": _card(20, 20, quick=False)}
    assert sc.check(_card(3, 4), base) == []  # one run flipped: within the spread of p = 21/22 over 4
    assert sc.check(_card(2, 4), base)  # two: beyond it
    assert sc.check(_card(4, 4, extra=2), base)  # two new extra confirmed findings
    assert sc.check(_card(4, 4, extra=1), base) == []


def test_a_real_recording_is_compared_file_by_file():
    base = {"quick": _card(0, 0, files={"a.ulg": True, "b.ulg": False}),
            "full": _card(0, 0, files={"a.ulg": True, "b.ulg": False}, quick=False)}
    assert sc.check(_card(0, 0, files={"a.ulg": True}), base) == []  # b missing here: not compared
    assert sc.check(_card(0, 0, files={"a.ulg": False, "b.ulg": True}), base) == ["w: a.ulg no longer diagnosed right"]


def test_extra_confirmed_is_a_systematic_finding_matching_no_hidden_effect():
    rec = {"truth": [{"cause": "force_offset", "channel": "f1", "value": 50.0}, {"cause": "force_noise", "value": 2.0}],
           "findings": [{"cause": "force_offset", "channel": "f1", "estimate": 50.1, "interval": [49.0, 51.0],
                         "confirmed": True},
                        {"cause": "parameter_error", "parameter": "k3", "estimate": 0.95, "interval": [0.94, 0.96],
                         "confirmed": True},
                        {"cause": "force_delay", "channel": "f2", "estimate": 1e-4, "interval": [0, 2e-4],
                         "confirmed": False},
                        {"cause": "force_noise", "estimate": 2.1, "interval": [1.9, 2.3], "estimate_kind": "estimate"}]}
    s = sc.score_run("vehicle", rec)
    assert s["right"] and s["confirmed"]
    assert [e.split("=")[0] for e in s["extra_confirmed"]] == ["parameter_error:k3"]  # the unconfirmed delay is no claim
    assert s["coverage"] == {"force_offset": True, "force_noise/estimate": True}


def test_a_body_that_is_not_rigid_names_the_missing_degree_of_freedom_not_its_frequency():
    """A ``model_form`` finding on the body names a bending chassis (an ``unmodelled_mode`` truth) first,
    and the frequency it says the mode rings at counts in the 10 % measure; on an axle it names no mode."""
    truth = [{"cause": "unmodelled_mode", "value": 26.3}, {"cause": "force_noise", "value": 2.4}]
    body = {"cause": "model_form", "channel": "moment", "axle": "body", "estimate": 102.0, "frequency_hz": 25.5,
            "confirmed": False}
    s = sc.score_run("vehicle", {"truth": truth, "findings": [body]})
    assert s["right"] and not s["extra_confirmed"]
    assert s["coverage"]["unmodelled_mode/within_10pct"] is True
    far = dict(body, frequency_hz=30.0)
    assert sc.score_run("vehicle", {"truth": truth, "findings": [far]})["coverage"]["unmodelled_mode/within_10pct"] is False
    axle = dict(body, axle="front")
    assert not sc.score_run("vehicle", {"truth": truth, "findings": [axle]})["right"]


def test_an_optional_truth_named_is_no_claim_and_not_naming_it_is_no_miss():
    """A degree of freedom the world has but does not ask for (the whole car's roll, the inclined
    struts' turning: ``optional``): a body finding that names it is no extra claim and no false alarm
    on an effect-free run, and is left out of the order; its coverage key is the truth's ``named_as``."""
    truth = [{"cause": "unmodelled_mode", "value": None, "optional": True, "named_as": "struts"},
             {"cause": "force_scale", "channel": "f1", "value": 1.03}, {"cause": "force_noise", "value": 1.0}]
    body = {"cause": "model_form", "channel": "moment", "axle": "body", "estimate": 12.0, "confirmed": False}
    scale = {"cause": "force_scale", "channel": "f1", "estimate": 1.031, "interval": [1.02, 1.04], "confirmed": True}
    s = sc.score_run("vehicle", {"truth": truth, "findings": [body, scale]})
    assert s["right"] and s["confirmed"] and not s["extra_confirmed"] and s["coverage"]["struts/named"] is True
    free = [truth[0], truth[2]]
    s = sc.score_run("vehicle", {"truth": free, "findings": [body]})
    assert s["false_alarm"] is False and s["coverage"]["struts/named"] is True
    s = sc.score_run("vehicle", {"truth": free, "findings": [dict(body, axle="front")]})  # an axle's is a claim
    assert s["false_alarm"] is True and s["coverage"]["struts/named"] is False
    roll = [{"cause": "unmodelled_mode", "value": 1.7, "optional": True}, truth[2]]  # older truths: roll
    assert sc.score_run("vehicle", {"truth": roll, "findings": []})["coverage"]["roll/named"] is False


def test_a_constant_bias_at_the_level_a_walk_held_is_no_extra_claim():
    walk = {"cause": "gyro_bias_drift", "channel": "wx", "value": 6.7e-4, "visibility": 4.0,
            "realised": {"mean": -9.0e-3, "std": 1.0e-3}}
    named = {"cause": "gyro_bias", "channel": "wx", "estimate": -9.3e-3, "interval": [-12.2e-3, -6.5e-3]}
    s = sc.score_run("attitude", {"truth": [walk], "findings": [named]})
    assert s["extra_confirmed"] == []
    # a level the walk never held (beyond its interval and twice the walk's spread) is a claim
    off = dict(named, estimate=9.3e-3, interval=[6.5e-3, 12.2e-3])
    assert sc.score_run("attitude", {"truth": [walk], "findings": [off]})["extra_confirmed"]
    # and a walk whose level is not recorded (an older truth) leaves the rule as it was
    plain = {k: v for k, v in walk.items() if k != "realised"}
    assert sc.score_run("attitude", {"truth": [plain], "findings": [named]})["extra_confirmed"]
    # where the walk is in sight, it is still asked for
    seen = dict(walk, visibility=40.0)
    assert not sc.score_run("attitude", {"truth": [seen], "findings": [named]}).get("right")
