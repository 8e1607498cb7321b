"""Controllers on the multirotor plant in wind against the ideal plant, paired (docs/plant.md).

    flock /tmp/dualpilot-heavy.lock .venv/bin/python benchmarks/plant_winds.py \\
        --missions 200 --profile today --winds 0,5,10 --out runs/plant-winds \\
        --figure docs/figures/plant_success_wind.png

Runs ``dualpilot evaluate`` on the same missions (``--seed``, paper timing) once with the
ideal plant (``OUT/ideal``) and once per mean wind with the multirotor plant
(``OUT/w<wind>``: ``--turbulence``, ``--gps-sigma``, the "auto" tube; on a fire-behaviour
``--scenario`` the one mean wind is the scenario's own, that of its fire); a directory that
already holds a results.csv is read, not run again (``--reuse``). ``--concurrent NAME=VALUE``
(repeatable) is passed to every run, the ideal plant's too (e.g. ``reanchor_tol=tube``, the
re-anchoring reading of docs/plant.md), and ``--set NAME=VALUE`` (repeatable) likewise (e.g.
``no_plan=escape``). Prints a Markdown table per
controller and plant: success, ``tracking_breach``, ``fire_contact``, mean time and energy
over the missions completed, the tracking error (median over the missions that flew of each
mission's p50 and p99, and the largest p99), the missions' summed wall time, and the success
paired with the ideal plant's on the same missions: the difference in points, the discordant
pairs and McNemar's exact test (a two-sided binomial test on them, ``scipy.stats.binomtest``).
With ``--figure``: success against wind speed, one line per controller, the ideal plant's
success a dashed line of the same colour.
"""

from __future__ import annotations

import argparse
import statistics
from pathlib import Path

import harness

from dualpilot.model.scenarios import get_scenario

Rows = dict[tuple[str, str], dict[str, str]]


def evaluate(args: argparse.Namespace, out: Path, extra: list[str]) -> Rows:
    """Rows of one ``dualpilot evaluate`` run, keyed (mission, controller); run unless reused."""
    if not (args.reuse and (out / "results.csv").exists()):
        harness.run_evaluate(args.missions, args.seed, args.jobs, args.controllers, out,
                             [*args.where, *extra])
    return harness.read_results(out)


def _mean(values: list[float]) -> str:
    return f"{statistics.fmean(values):.1f}" if values else "-"


def row(name: str, plant: str, rows: list[dict[str, str]], ideal: list[dict[str, str]]) -> str:
    """One Markdown row: ``rows`` of one controller and plant, paired with ``ideal``'s."""
    n = len(rows)
    ok = [r for r in rows if r["success"] == "1"]
    flew = [r for r in rows if r["tracking_error_p50_m"]]  # a mission of 0 steps has none
    p50 = [float(r["tracking_error_p50_m"]) for r in flew]
    p99 = [float(r["tracking_error_p99_m"]) for r in flew]
    track = (f"{statistics.median(p50):.2f} / {statistics.median(p99):.2f} "
             f"({max(p99):.2f})") if p99 and max(p99) > 0 else "0"
    paired = "- | - | -"
    if rows is not ideal:
        only_i, only_m, mcnemar = harness.mcnemar(zip(ideal, rows, strict=True))
        p = "-" if mcnemar is None else f"{mcnemar:.3f}"
        paired = f"{100 * (only_m - only_i) / n:+.1f} | {only_i} / {only_m} | {p}"
    return (f"| {name} | {plant} | {100 * len(ok) / n:.1f} % | "
            f"{sum(r['tracking_breach'] == '1' for r in rows)} | "
            f"{sum(r['failure_cause'] == 'fire_contact' for r in rows)} | "
            f"{_mean([float(r['mission_time_s']) for r in ok])} | "
            f"{_mean([float(r['energy']) for r in ok])} | {track} | "
            f"{sum(float(r['wall_s']) for r in rows):.1f} | {paired} |")


def figure(path: Path, names: list[str], winds: list[float],
           success: dict[str, list[float]], ideal: dict[str, float], title: str) -> None:
    """Success (%) against wind speed, one line per controller, the ideal plant dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.6, 4.2))
    at = min(winds) - 0.3 * max(max(winds) - min(winds), 5.0)  # the ideal plant's column
    for i, name in enumerate(names):
        colour = f"C{i}"
        ax.plot(winds, success[name], "o-", color=colour, label=name)
        ax.axhline(ideal[name], color=colour, linestyle="--", linewidth=0.8, alpha=0.7)
        ax.plot([at], [ideal[name]], "s", color=colour, markerfacecolor="none")
    ax.plot([], [], "ks--", markerfacecolor="none", linewidth=0.8,
            label="ideal plant (no wind)")
    ax.set_xlabel("mean wind (m/s), multirotor plant")
    ax.set_ylabel("success (%)")
    ax.set_xticks([at, *winds], ["ideal", *(f"{w:g}" for w in winds)])
    ax.set_ylim(-2, 102)
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--missions", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--controllers", default="s1,s2,cc,concurrent,lookahead+risk")
    ap.add_argument("--profile", help="a readings profile (evaluate's --profile)")
    ap.add_argument("--scenario", help="a fire-behaviour scenario (evaluate's --scenario)")
    ap.add_argument("--winds", default="0,5,10",
                    help="mean winds (m/s), comma-separated (on a --scenario: its own wind)")
    ap.add_argument("--turbulence", default="moderate")
    ap.add_argument("--gps-sigma", type=float, default=1.5, help="gps_sigma_m (m)")
    ap.add_argument("--concurrent", action="append", default=[], metavar="NAME=VALUE",
                    help="a concurrent supervisor parameter for every run (evaluate's)")
    ap.add_argument("--set", dest="settings", action="append", default=[],
                    metavar="NAME=VALUE", help="a reading for every run (evaluate's --set)")
    ap.add_argument("--reuse", action="store_true", help="read a run that already has rows")
    ap.add_argument("--out", type=Path, default=Path("runs/plant-winds"))
    ap.add_argument("--figure", type=Path, help="write the success-against-wind figure here")
    args = ap.parse_args()
    args.where = ([f"--profile={args.profile}"] if args.profile else []) + (
        [f"--scenario={args.scenario}"] if args.scenario else []) + [
        f"--concurrent={item}" for item in args.concurrent] + [
        f"--set={item}" for item in args.settings]
    names = args.controllers.split(",")
    own = get_scenario(args.scenario).params.wind_speed_mps if args.scenario else None
    winds = [own] if own is not None else [float(w) for w in args.winds.split(",")]
    ideal = evaluate(args, args.out / "ideal", [])
    runs = {w: evaluate(args, args.out / f"w{w:g}",
                        ["--set", "plant=multirotor", "--set", f"turbulence={args.turbulence}",
                         "--set", f"gps_sigma_m={args.gps_sigma:g}",
                         *([] if own is not None else ["--set", f"wind_speed_mps={w:g}"])])
            for w in winds}
    where = ", ".join(f"{k} {v}" for k, v in (("profile", args.profile),
                                               ("scenario", args.scenario)) if v) or "paper"
    print(f"{args.missions} missions from seed {args.seed}, {where}, paper timing; multirotor: "
          f"{args.turbulence} turbulence, gps_sigma_m = {args.gps_sigma:g}, the auto tube"
          + "".join(f"; --concurrent {item}" for item in args.concurrent)
          + "".join(f"; --set {item}" for item in args.settings) + "\n")
    print("| controller | plant, wind | success | `tracking_breach` | fire contact | time (s) | "
          "energy (N²) | tracking error p50 / p99 (max p99), m | wall, s | Δ success vs "
          "ideal, points | discordant (ideal only / multirotor only) | McNemar p |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    success: dict[str, list[float]] = {}
    base: dict[str, float] = {}
    for name in names:
        keys = sorted((k for k in ideal if k[1] == name), key=lambda k: int(k[0]))
        ideal_rows = [ideal[k] for k in keys]
        print(row(name, "ideal", ideal_rows, ideal_rows))
        base[name] = 100 * sum(r["success"] == "1" for r in ideal_rows) / len(keys)
        success[name] = []
        for w in winds:
            rows = [runs[w][k] for k in keys]
            print(row(name, f"multirotor, {w:g} m/s", rows, ideal_rows))
            success[name].append(100 * sum(r["success"] == "1" for r in rows) / len(keys))
    if args.figure:
        figure(args.figure, names, winds, success, base,
               f"{args.missions} missions, {where}: multirotor, {args.turbulence} turbulence, "
               f"gps σ {args.gps_sigma:g} m")


if __name__ == "__main__":
    main()
