"""The Monte-Carlo sweep: a grid of readings × controllers × N missions, on Dask distributed.

Every grid point flies the same configurations (:mod:`dualpilot.evaluation.missions`);
the rows go to one tidy table, ``results.csv`` / ``results.parquet``
(:data:`SWEEP_COLUMNS`), with a summary per point and controller
(:mod:`dualpilot.evaluation.stats`). ``dualpilot evaluate`` is the one-point case
(:mod:`dualpilot.evaluation.evaluate`).
"""

from __future__ import annotations

import itertools
import json
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from dualpilot.evaluation.missions import (
    COLUMNS,
    CONTROLLERS,
    ORACLE,
    Settings,
    Task,
    check_dimensions,
    other_flags,
)
from dualpilot.evaluation.results import check_config, read_results, write_parquet
from dualpilot.evaluation.runner import run
from dualpilot.evaluation.stats import summarize
from dualpilot.evaluation.yardstick import yardstick
from dualpilot.mission.config import MissionConfig
from dualpilot.readings import get_profile, parse_value, settable

#: the sweep's tidy table: the grid point and every parameter value, then COLUMNS
SWEEP_COLUMNS = ["point", "label", "profile", *settable(), *COLUMNS]


@dataclass(frozen=True)
class Point:
    """One grid point: a profile and the settings applied on top of it."""

    index: int
    profile: str
    settings: Settings

    def config(self, base: MissionConfig) -> MissionConfig:
        """``base`` with this point's reading."""
        return replace(base, profile=self.profile, settings=self.settings)

    @property
    def label(self) -> str:
        parts = [f"profile={self.profile}"] + [f"{k}={_text(v)}" for k, v in self.settings]
        return " ".join(parts)


def _text(v: Any) -> str:
    return "none" if v is None else str(v).lower() if isinstance(v, bool) else str(v)


def _value(name: str, v: Any) -> Any:
    return parse_value(name, _text(v))


def grid_points(axes: Mapping[str, Sequence[Any]], profile: str = "today",
                points: Sequence[Mapping[str, Any]] = ()) -> list[Point]:
    """The cartesian product of ``axes`` (name → values; "profile" may be one), then ``points``.

    Each point's settings are checked by building its profile.
    """
    out: list[Point] = []
    combos: list[dict[str, Any]] = []
    if axes:
        names = list(axes)
        combos = [dict(zip(names, vals, strict=True))
                  for vals in itertools.product(*(axes[n] for n in names))]
    elif not points:
        combos = [{}]
    for combo in [*combos, *points]:
        combo = dict(combo)
        prof = str(combo.pop("profile", profile))
        settings = tuple((k, _value(k, v)) for k, v in combo.items())
        p = Point(len(out), prof, settings)
        get_profile(prof).with_settings(dict(settings))  # raises on a bad value
        out.append(p)
    return out


def parse_axes(items: Sequence[str]) -> dict[str, list[str]]:
    """Repeated ``--set name=v1,v2`` flags as grid axes."""
    axes: dict[str, list[str]] = {}
    for item in items:
        key, sep, values = item.partition("=")
        if not sep or not key.strip():
            raise ValueError(f"a grid axis is 'name=v1,v2,...', got {item!r}")
        axes[key.strip()] = [v.strip() for v in values.split(",")]
    return axes


def load_grid(path: Path) -> dict[str, Any]:
    """A sweep file (YAML): ``profile``, ``grid`` (name → values), ``points`` (list of dicts),
    and optionally ``missions``, ``controllers``, ``seed``, ``timing``."""
    import yaml

    doc = yaml.safe_load(path.read_text()) or {}
    if not isinstance(doc, dict):
        raise ValueError(f"{path}: a sweep file is a mapping")
    unknown = set(doc) - {"profile", "grid", "points", "missions", "controllers", "seed",
                          "timing", "s2_method"}
    if unknown:
        raise ValueError(f"{path}: unknown keys {sorted(unknown)}")
    return doc


def sweep(points: Sequence[Point], missions: int, out: Path, base: MissionConfig | None = None,
          controllers: Sequence[str] = CONTROLLERS, jobs: int | None = None,
          scheduler: str | None = None, progress: bool = True, processes: bool = True,
          figure: Callable[[dict[str, Any], Path], Path] | None = None) -> dict[str, Any]:
    """Run (or resume) the sweep in ``out``: results.csv/.parquet, summary.json and, with
    ``figure`` (dualpilot.viz.sweep.plot_sweep), fig_sweep.png. Every task is ``base``
    (its seed the run's, its timing, methods and parameters every mission's) with a point's
    reading, flown by one of ``controllers``."""
    base = base or MissionConfig()
    seed, timing = base.seed, base.timing.value
    for p in points:
        check_dimensions(p.config(base), controllers)
    out.mkdir(parents=True, exist_ok=True)
    config: dict[str, Any] = {"seed": seed, "timing": timing, "s2_method": base.system2_method,
                              "points": [p.label for p in points]}
    if other_flags(base):
        config["config"] = other_flags(base)
    check_config(out, {k: v for k, v in config.items() if k != "points"})
    tasks = [Task.of(i, seed, c, p.config(base), point=p.index, label=p.label)
             for i in range(missions) for p in points for c in controllers]
    path = out / "results.csv"
    wall = run(tasks, path, SWEEP_COLUMNS, ("label", "mission", "controller"),
               jobs or os.cpu_count() or 1, scheduler, progress, processes)
    rows = read_results(path)
    write_parquet(path, out / "results.parquet")
    summary: dict[str, Any] = {**config, "missions": missions, "wall_s": wall,
                               "controllers": list(controllers), "points": []}
    for p in points:
        mine = [r for r in rows if r["label"] == p.label and int(r["mission"]) < missions]
        s = summarize(mine, missions, timing)
        entry = {"point": p.index, "label": p.label, "profile": p.profile,
                 "settings": dict(p.settings), "controllers": s["controllers"]}
        if ORACLE in controllers:  # asserts no completed mission is called impossible
            entry["yardstick"] = yardstick(mine, Task.of(0, seed, ORACLE, p.config(base)).config)
        summary["points"].append(entry)
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    if figure is not None:
        summary["figure"] = str(figure(summary, out / "fig_sweep.png"))
    return summary
