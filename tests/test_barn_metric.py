"""BARN's score and report: the published DWA rows summarised as BARN's report_test.py does."""

from __future__ import annotations

import pytest

from bulletnav.barn import data, metric


def _report_t_opt() -> dict[int, float]:
    # report_test.py lines 40-51: t_opt of the 50 test worlds from its own start (-2, 3)
    return {i: metric.optimal_time(data.load_world(i).path_cells, metric.REPORT_START) for i in metric.TEST_WORLDS}


def test_dwa_rows_summary_matches_barns_report_script():
    rows = data.dwa_rows()
    assert len(rows) == 500 and sorted({r.world for r in rows}) == list(range(0, 300, 6))
    assert (sum(r.success for r in rows), sum(r.collided for r in rows), sum(r.timeout for r in rows)) == (425, 28, 47)
    # Expected line: BARN's own report_test.py (commit bf5a226) run once by hand on res/dwa_out.txt
    # (python report_test.py --out_path res/dwa_out.txt, with numpy.load forced to allow_pickle=False).
    # BARN's README quotes "Avg Time: 33.4715, Avg Metric: 0.1693, Avg Success: 0.8800, Avg Collision:
    # 0.0480, Avg Timeout: 0.0720", which these rows do not give (425/500 successes is 0.85); the rows
    # give the success, collision and time-out of the README's earlier line (before 2022-04-05:
    # "Avg Time: 39.5296, Avg Metric: 0.1577, Avg Success: 0.8500, Avg Collision: 0.0560, Avg Timeout: 0.0940").
    assert metric.summarise(rows, _report_t_opt()).line() == (
        "Avg Time: 34.0925, Avg Metric: 0.1592, Avg Success: 0.8500, Avg Collision: 0.0560, Avg Timeout: 0.0940")
    # the same script with its lower clip at 4 t_opt (report_test.py before 2026-03-04), also run by hand
    assert f"{metric.summarise(rows, _report_t_opt(), low=4).metric:.4f}" == "0.1580"


def test_reference_lengths_agree_with_barns_2022_sixth_column():
    # dwa_out.txt's sixth column was written by run.py of 2022-03-28 (commit 3f77441) as
    # time / (path_length / 2), path_length measured from the start (-2, 3): per world its ratio to
    # time / t_opt computed here is 1 up to the rows' rounding and sampling jitter (< 1e-3), and run.py's
    # present start (-2.25, 3) does not give that
    t_opt = _report_t_opt()
    t_run = {i: metric.optimal_time(data.load_world(i).path_cells) for i in metric.TEST_WORLDS}
    lines = [line.split() for line in data.DWA_FILE.read_text().splitlines()]
    ok = [(int(w), float(t), float(m)) for w, s, _, _, t, m in lines if s == "1"]
    worst = max(abs(m / (t / t_opt[w]) - 1) for w, t, m in ok)
    assert worst < 1e-3
    assert max(abs(m / (t / t_run[w]) - 1) for w, t, m in ok) > 1e-2


def test_barn_metric_by_hand():
    # t_opt = 10 s: clipped to [20, 80] s
    assert metric.barn_metric(True, 15.0, 10.0) == pytest.approx(0.5)
    assert metric.barn_metric(True, 50.0, 10.0) == pytest.approx(0.2)
    assert metric.barn_metric(True, 99.0, 10.0) == pytest.approx(0.125)
    assert metric.barn_metric(False, 15.0, 10.0) == 0.0
    assert metric.barn_metric(True, 15.0, 10.0, low=4) == pytest.approx(0.25)


def test_reference_path_length_by_hand():
    # two cells (10, 0) and (10, 1): points (-3.075, 5.075), (-3.075, 5.225); start (-3.075, 3), goal (-3.075, 13)
    cells = [[10, 0], [10, 1]]
    assert metric.reference_path_length(cells, (-3.075, 3.0)) == pytest.approx(10.0)
    assert metric.optimal_time(cells, (-3.075, 3.0)) == pytest.approx(5.0)
    # run.py's start (-2.25, 3): legs hypot(0.825, 2.075) to the first cell and hypot(0.825, 7.775) from the last
    expected = (0.825 ** 2 + 2.075 ** 2) ** 0.5 + 0.15 + (0.825 ** 2 + 7.775 ** 2) ** 0.5
    assert metric.reference_path_length(cells) == pytest.approx(expected)


def test_bad_out_line_is_named():
    with pytest.raises(metric.BarnFileError, match=r"my_out.txt: line 2: .*'6 1 x'"):
        metric.parse_out("0 1 0 0 12.5 1.0\n6 1 x\n", "my_out.txt")
