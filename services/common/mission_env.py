"""The mission's environment names: how docker compose (or a shell) sets a mission.

A mission's configuration enters the stack once, at the supervisor
(:class:`~dualpilot.mission.config.MissionConfig`), which sends it whole to the
planners, the EWS and uavsim. Each name below stands for one flag of
:func:`dualpilot.mission.config_args.add_config_arguments`; :func:`env_argv`
turns an environment into those flags, which the supervisor reads before its
command line (services/supervisor/options.py), so a flag given there wins (a
repeatable one adds to the environment's). This is the only module that reads
these names; no other process reads any of them.

=========================  ==========================  ================================
environment                flag                        example
=========================  ==========================  ================================
CONTROLLER                 --controller                cc, s1, s2, concurrent+risk, …
SUPERVISOR                 --supervisor                paper, concurrent, lookahead
MISSION_SEED               --seed                      7
TIMING                     --timing                    paper, measured
READINGS_PROFILE           --profile                   today, literal, fig-r5
READINGS                   --set (each)                "zeta=0.35;u_max_n=6"
D_T_READING                --d-t-reading               active, newborn, hull
FAILURE_RULE               --failure-rule              any, newborn, become
FIRE_SUBSTEPS_PER_MOTION   --fire-substeps-per-motion  0
FIRE_LIFE_BASE             --fire-life-base            substep, step
FIRE_EXTENT                --fire-extent               substep, step, birth
FIRE_REDRAW_CLEARANCE      --redraw-clearance          true, false
ATTENTION_DRAW             --attention-draw            sample, argmax
SPEED_LIMIT                --speed-limit               axis, norm
FIRE_SCENARIO              --scenario                  paper, grass-5, shrub, …
IGNITION_CLEARANCE_M       --ignition-clearance        20
MAX_STEPS                  --max-steps                 150
S1_METHOD                  --s1-method                 rrt, rrt+du
S2_METHOD                  --s2-method                 fast, exact, fast+exact, …
S2_TIME_LIMIT_S            --s2-time-limit-s           60
CONCURRENT_PARAMS          --concurrent (each)         "check_steps=5;risk.alpha=0.1"
FORECAST_PARAMS            --forecast (each)           "members=32;resolution_m=20"
GOAL                       --goal                      900,900,100,100
AREA_SIZE_M                --area-size-m               1000
MISSION_START              --start                     50,50 (in-process only)
MISSION_ID                 --mission-id                run-7
=========================  ==========================  ================================

An empty value is no value (the flag's default). A list (READINGS,
CONCURRENT_PARAMS, FORECAST_PARAMS) separates its items with ``;``.
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = ["MISSION_ENV", "env_argv", "help_text", "without_mission_env"]

#: (environment name, flag, whether it holds a ';'-separated list of the flag's values)
MISSION_ENV: tuple[tuple[str, str, bool], ...] = (
    ("CONTROLLER", "--controller", False),
    ("SUPERVISOR", "--supervisor", False),
    ("MISSION_SEED", "--seed", False),
    ("TIMING", "--timing", False),
    ("READINGS_PROFILE", "--profile", False),
    ("READINGS", "--set", True),
    ("D_T_READING", "--d-t-reading", False),
    ("FAILURE_RULE", "--failure-rule", False),
    ("FIRE_SUBSTEPS_PER_MOTION", "--fire-substeps-per-motion", False),
    ("FIRE_LIFE_BASE", "--fire-life-base", False),
    ("FIRE_EXTENT", "--fire-extent", False),
    ("FIRE_REDRAW_CLEARANCE", "--redraw-clearance", False),
    ("ATTENTION_DRAW", "--attention-draw", False),
    ("SPEED_LIMIT", "--speed-limit", False),
    ("FIRE_SCENARIO", "--scenario", False),
    ("IGNITION_CLEARANCE_M", "--ignition-clearance", False),
    ("MAX_STEPS", "--max-steps", False),
    ("S1_METHOD", "--s1-method", False),
    ("S2_METHOD", "--s2-method", False),
    ("S2_TIME_LIMIT_S", "--s2-time-limit-s", False),
    ("CONCURRENT_PARAMS", "--concurrent", True),
    ("FORECAST_PARAMS", "--forecast", True),
    ("GOAL", "--goal", False),
    ("AREA_SIZE_M", "--area-size-m", False),
    ("MISSION_START", "--start", False),
    ("MISSION_ID", "--mission-id", False),
)


def env_argv(environ: Mapping[str, str]) -> list[str]:
    """The configuration flags ``environ`` says, each ``--flag=value`` (so a value that starts
    with "-" stays a value); a list's items one flag each, an empty value none."""
    argv: list[str] = []
    for name, flag, is_list in MISSION_ENV:
        text = environ.get(name, "").strip()
        if not text:
            continue
        items = [t.strip() for t in text.split(";") if t.strip()] if is_list else [text]
        argv += [f"{flag}={item}" for item in items]
    return argv


def without_mission_env(environ: Mapping[str, str]) -> dict[str, str]:
    """``environ`` without the mission's names: the environment of a process whose mission
    comes as flags (none is inherited from a launcher's shell or the compose file)."""
    names = {name for name, _, _ in MISSION_ENV}
    return {k: v for k, v in environ.items() if k not in names}


def help_text() -> str:
    """The table for a ``--help``: each environment name and its flag."""
    width = max(len(name) for name, _, _ in MISSION_ENV)
    rows = [f"  {name:<{width}}  {flag}" + ("  (items 'a=1;b=2')" if is_list else "")
            for name, flag, is_list in MISSION_ENV]
    return ("the mission configuration from the environment (a flag on the command line "
            "wins):\n" + "\n".join(rows))
