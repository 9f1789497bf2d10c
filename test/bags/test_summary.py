"""The replay summary's CoM region margin statistics, on hand-made reports."""

from __future__ import annotations

import json
import math

from awp_ros_msgs.msg import FeasibilityReport
import numpy as np

from awp_ros.bags.summary import summarize_reports

S = FeasibilityReport


def report(i: int, support: float, fwp: float, feasible: float, *, fresh: bool,
           status: int = S.STATUS_OK, fws_at: int = 0) -> FeasibilityReport:
    # fresh: the FWS was computed for this report; else it carries the one of stamp fws_at.
    r = FeasibilityReport(status=status)
    r.header.stamp.sec = i
    r.fws_stamp.sec = i if fresh else fws_at
    r.support_region_margin, r.fwp_region_margin = support, fwp
    r.feasible_region_margin = feasible
    return r


def test_region_margins_exclude_nan_count_empty_and_take_every_cycle():
    rng = np.random.default_rng(0)
    support = rng.uniform(-0.05, 0.3, 40)
    support[[3, 7]] = math.nan                               # empty regions
    fwp = support - 0.01
    feasible = support - 0.02
    fresh = np.arange(40) % 4 == 0
    reports = [report(i, support[i], fwp[i], feasible[i], fresh=bool(fresh[i]),
                      fws_at=i - i % 4) for i in range(40)]
    reports.append(report(99, 5.0, 5.0, 5.0, fresh=True, status=S.STATUS_INVALID_INPUT))
    s = summarize_reports(reports)
    assert s.valid == 40 and s.invalid == 1
    for name, values in (('support_region', support), ('fwp_region', fwp),
                         ('feasible_region', feasible)):
        st = s.region_margins[name]
        x = values[np.isfinite(values)]
        assert st['n'] == x.size and st['empty'] == values.size - x.size
        assert st['min'] == x.min() and st['max'] == x.max()
        assert st['median'] == np.median(x) and st['mean'] == x.mean()
        assert st['p5'] == np.percentile(x, 5)
    assert s.region_margins['support_region']['empty'] == 2
    assert s.region_margins['feasible_region']['n'] == 38     # every cycle's, not only FWS's
    assert s.margins['fws_margin']['n'] == 10     # the FWS margin: each FWS once
    text = s.to_text()
    assert 'region [m]' in text and 'feasible_region' in text
    json.dumps(s.to_dict(), allow_nan=False)


def test_regions_all_empty_give_null_statistics():
    s = summarize_reports([report(i, math.nan, math.nan, math.nan, fresh=True)
                           for i in range(3)])
    for st in s.region_margins.values():
        assert st['n'] == 0 and st['empty'] == 3 and st['median'] is None
    doc = json.loads(json.dumps(s.to_dict(), allow_nan=False))
    assert doc['region_margins']['feasible_region']['min'] is None
    assert 'feasible_region' in s.to_text()


def test_each_fws_margin_counts_once_also_when_released_lagged():
    # fws_lag_s: FWS of stamps 0, 10, 20 released at 3, 13, 23 (carried until the next);
    # none before 3 (NaN); the invalid report in between does not count.
    reports = []
    for i in range(30):
        r = report(i, 0.1, 0.1, 0.1, fresh=False, fws_at=(i - 3) // 10 * 10)
        r.fws_margin = math.nan if i < 3 else 100.0 + (i - 3) // 10
        reports.append(r)
    reports[15].status = S.STATUS_INVALID_INPUT
    s = summarize_reports(reports)
    st = s.margins['fws_margin']
    assert st['n'] == 3 and st['min'] == 100.0 and st['max'] == 102.0


def test_an_outside_reports_own_margin_counts_once_and_the_latest_fws_is_not_recounted():
    # FWS of stamp 0 carried by 0-9; 4-5 outside the FWS carry their own margins (their
    # stamps); 6-9 return to the FWS of stamp 0: counted once, with 4 and 5: 3 margins.
    reports = []
    for i in range(10):
        own = i in (4, 5)
        r = report(i, 0.1, 0.1, 0.1, fresh=own or i == 0, fws_at=0)
        r.fws_margin = -float(i) if own else 50.0
        reports.append(r)
    st = summarize_reports(reports).margins['fws_margin']
    assert st['n'] == 3 and st['min'] == -5.0 and st['max'] == 50.0
