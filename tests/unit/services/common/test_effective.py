"""Each process's effective configurations (services/common/effective.py): what a status says."""

from __future__ import annotations

import json

from dualpilot.mission.config import MissionConfig
from services.common.convert.config import config_from_json, config_to_json
from services.common.effective import Effective, plain


def test_a_process_keeps_its_newest_missions_as_json() -> None:
    eff = Effective(keep=2)
    config = MissionConfig.named("s2+risk", seed=4, system2_time_limit_s=3.0)
    for mid in ("a", "b", "c"):
        eff.record(mid, "u1", config_to_json(config), dynamics=config.spec().dynamics)
    eff.record("b", "u2", {})  # taken up again: the newest
    got = eff.snapshot()
    assert list(got) == ["c", "b"] and got["b"] == {"uav": "u2", "config": {}, "made": {}}
    assert config_from_json(got["c"]["config"]) == config
    assert got["c"]["made"]["dynamics"]["speed_limit"] == "axis"
    assert json.loads(json.dumps(got)) == got  # a status reply carries it as it is


def test_plain_is_json_data() -> None:
    assert plain((1.5, None, True)) == [1.5, None, True]
    assert plain(MissionConfig().forecast) == {"members": 32, "resolution_m": 10.0,
                                               "horizon_s": 40.0, "interval_s": 1.0}
