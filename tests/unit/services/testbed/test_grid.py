"""The test bed grid's pure parts: its cells, rounds, mission rows, summaries and pairing."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from services.testbed import grid
from services.testbed.fleet import topology
from services.testbed.impairment import Impairment
from services.testbed.topology import netns_name, owner

BENCHMARKS = Path(__file__).resolve().parents[4] / "benchmarks"


def test_the_cells_change_one_factor_at_a_time_from_clean() -> None:
    cells = grid.cells()
    assert [c.name for c in cells] == [
        "clean", "latency-100ms", "latency-300ms", "latency-1000ms", "loss-5pct", "loss-20pct",
        "rate-10mbit", "rate-1mbit", "rate-0.25mbit", "outage-5s", "outage-30s",
        "goal-300ms-5pct"]
    clean = cells[0]
    assert clean.impairment() == Impairment() and clean.outage_s == 0
    fields = ("latency_ms", "loss", "rate_mbit", "outage_s")
    for c in cells[1:-1]:
        changed = [f for f in fields if getattr(c, f) != getattr(clean, f)]
        assert changed == [c.factor] and getattr(c, c.factor) == c.level
    goal = cells[-1]
    assert (goal.latency_ms, goal.loss, goal.rate_mbit, goal.outage_s) == (300.0, 0.05, None, 0)
    by = {c.name: c for c in cells}
    assert by["rate-0.25mbit"].impairment() == Impairment(rate_mbit=0.25)
    assert by["latency-1000ms"].impairment() == Impairment(delay_ms=1000.0)
    assert by["outage-30s"].wire()["outage_at_step"] == 12
    assert by["loss-20pct"].wire()["outage_at_step"] is None


def test_cells_by_name_keep_the_grid_order_and_refuse_unknown_names() -> None:
    assert [c.name for c in grid.cells(["goal-300ms-5pct", "clean"])] == ["clean",
                                                                          "goal-300ms-5pct"]
    with pytest.raises(KeyError, match="latency-200ms"):
        grid.cells(["latency-200ms"])


def test_rounds_split_the_seeds_evenly_in_order() -> None:
    seeds = list(range(50))
    assert [len(r) for r in grid.rounds(seeds, 15)] == [13, 13, 12, 12]
    assert [len(r) for r in grid.rounds(seeds, 10)] == [10] * 5
    assert [len(r) for r in grid.rounds(seeds, 17)] == [17, 17, 16]
    assert grid.rounds(seeds, 64) == [seeds]
    assert sum(grid.rounds(seeds, 15), []) == seeds
    assert grid.rounds([3, 4, 5], 2) == [[3, 4], [5]]


def test_each_vehicle_has_its_own_link_to_the_ground() -> None:
    topo = topology(3)
    assert topo.hosts == ("ground", "air1", "air2", "air3")
    assert [(lk.name, lk.hosts) for lk in topo.links] == [
        ("radio1", ("air1", "ground")), ("radio2", ("air2", "ground")),
        ("radio3", ("air3", "ground"))]
    r2 = topo.links[1]
    assert topo.address(r2, "ground") == "10.10.2.1" and topo.address(r2, "air2") == "10.10.2.3"
    assert max(len(lk.wire_end(h)) for lk in topology(64).links for h in lk.hosts) <= 15
    with pytest.raises(ValueError):
        topology(0)
    # a fleet host's namespace is still recognised as its owner's (leftovers after a crash)
    assert owner(netns_name(4242, 3, "air12")) == (4242, 3)
    assert owner("dptb4242-3-12air") is None


def _step(t: int, system: int, faults: list[str] | None = None) -> dict[str, object]:
    return {"kind": "step", "t": t, "system": system, "faults": faults or []}


def test_a_row_reads_the_mission_and_its_link() -> None:
    cell = grid.cells(["goal-300ms-5pct"])[0]
    summary = {"success": True, "ending": "goal",
               "stack": {"faults": {"plan_deadline": 2, "fire_stale": 1},
                         "link": {"steps": {"ok": 2, "link_degraded": 1, "link_lost": 1}}}}
    steps = [_step(0, 2), _step(1, 2), _step(2, 1, ["link_lost"]), _step(3, 2)]
    wire = {"air_to_ground_bytes": 1000, "ground_to_air_bytes": 3000}
    r = grid.row(cell, "lookahead+risk", 7, "uav2", 1, summary, steps, wire, {"at_step": 12}, 0,
                 "cells/x/uav2")
    assert list(r) == list(grid.ROW_FIELDS)
    assert (r["cell"], r["factor"], r["level"], r["seed"]) == ("goal-300ms-5pct", "goal", "",
                                                               "7")
    assert (r["success"], r["ended"], r["steps"], r["s2_steps"], r["s2_share"]) == (
        "1", "1", "4", "3", "0.7500")
    assert (r["plan_deadline"], r["link_lost_steps"], r["link_degraded_steps"]) == ("2", "1", "1")
    assert (r["wire_bytes"], r["wire_bytes_per_step"], r["outage_at_step"]) == (
        "4000", "1000.0", "12")
    assert r["failure_cause"] == ""
    burnt = grid.row(cell, "lookahead+risk", 7, "uav2", 1, {**summary, "success": False,
                                                             "ending": "fire_contact"},
                     steps, wire, {}, 0, "d")
    assert (burnt["success"], burnt["ending"], burnt["failure_cause"]) == (
        "0", "fire_contact", "fire_contact")


def test_a_mission_that_never_ended_is_a_failure_and_its_faults_come_from_its_steps() -> None:
    cell = grid.cells(["loss-20pct"])[0]
    steps = [_step(0, 1, ["plan_deadline"]), _step(1, 1, ["plan_deadline: 2 in flight",
                                                          "link_lost"])]
    r = grid.row(cell, "concurrent+risk", 3, "uav1", 2, None, steps, {}, {}, None, "d")
    assert (r["success"], r["ended"], r["level"], r["s2_share"]) == ("0", "0", "0.2", "0.0000")
    assert r["failure_cause"] == "no_end"
    assert (r["plan_deadline"], r["link_lost_steps"], r["wire_bytes"], r["air_exit"]) == (
        "2", "1", "", "")
    # a summary written when the mission's time limit ran out has no ending
    cut: dict[str, object] = {"success": False, "ending": None, "stack": {"faults": {}}}
    r = grid.row(cell, "concurrent+risk", 3, "uav1", 2, cut, steps, {}, {}, 1, "d")
    assert (r["success"], r["ended"], r["ending"], r["plan_deadline"]) == ("0", "0", "", "2")


def _row(cell: str, seed: int, success: int, controller: str = "c", steps: int = 10,
         s2: int = 5, deadline: int = 0, wire: str = "") -> dict[str, str]:
    r = dict.fromkeys(grid.ROW_FIELDS, "")
    r.update(cell=cell, factor=cell, controller=controller, seed=str(seed),
             success=str(success), ended="1", steps=str(steps), s2_steps=str(s2),
             plan_deadline=str(deadline), link_lost_steps="0", wire_bytes=wire)
    return r


def test_the_summary_pools_steps_and_bytes_over_a_cells_missions() -> None:
    rows = [_row("clean", 0, 1, steps=4, s2=3, deadline=0, wire="4000"),
            _row("clean", 1, 0, steps=6, s2=1, deadline=3, wire=""),
            _row("clean", 2, 1, steps=10, s2=0, deadline=1, wire="2000"),
            _row("loss-5pct", 0, 1, controller="d")]
    rows[1]["ended"] = "0"
    out = grid.summarise(rows)
    assert [(e["cell"], e["controller"]) for e in out] == [("clean", "c"), ("loss-5pct", "d")]
    e = out[0]
    assert (e["missions"], e["successes"], e["success_rate"], e["unfinished"]) == (3, 2, 0.6667, 1)
    assert e["s2_share"] == pytest.approx(4 / 20)
    assert (e["plan_deadline"], e["plan_deadline_per_mission"],
            e["missions_with_deadline_miss"]) == (4, 1.333, 2)
    # 6000 bytes over the 14 steps of the two missions with counters
    assert e["wire_bytes_per_step"] == pytest.approx(428.6)
    assert out[1]["wire_bytes_per_step"] is None


def test_pairs_match_a_cell_to_clean_on_the_same_seeds_and_mcnemar_is_exact() -> None:
    sys.path.insert(0, str(BENCHMARKS))
    import harness

    # ten seeds: clean reaches the goal in all but seed 9; the cell fails seeds 0..7 and
    # reaches it in seed 9: 8 missions only clean completed, 1 only the cell
    rows = [_row("clean", s, int(s != 9)) for s in range(10)]
    rows += [_row("loss-20pct", s, int(s >= 8)) for s in range(10)]
    rows += [_row("loss-20pct", 10, 1), _row("clean", 3, 0, controller="other")]
    matched = grid.pairs(rows, "c", "clean", "loss-20pct")
    assert [a["seed"] for a, _ in matched] == [str(s) for s in range(10)]
    assert all(a["cell"] == "clean" and b["cell"] == "loss-20pct" for a, b in matched)
    only_clean, only_cell, p = harness.mcnemar(matched)
    assert (only_clean, only_cell) == (8, 1)
    # two-sided exact binomial on 9 discordant pairs: 2 * (C(9,0) + C(9,1)) / 2**9
    assert p == pytest.approx(20 / 512)
    delta, lo, hi = grid.paired_difference(matched)
    # differences: eight -1, one +1, one 0: mean -0.7, squared deviations 4.1, sd √(4.1/9)
    assert delta == pytest.approx(-70.0)
    assert (lo, hi) == (pytest.approx(-70.0 - 41.8337, abs=1e-3),
                        pytest.approx(-70.0 + 41.8337, abs=1e-3))
    assert grid.pairs(rows, "c", "clean", "outage-5s") == []
