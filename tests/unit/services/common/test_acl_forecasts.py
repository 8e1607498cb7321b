"""Access control for the forecasts by reference: the planners may ask ``ews/forecasts``,
only the EWS answers it, and nobody else gains a query by it (services/common/acl.py)."""

from __future__ import annotations

from typing import Any

from services.common import acl


def allowed(identity: str, message: str, flow: str) -> set[str]:
    """The key expressions ``identity`` may use ``message`` on in ``flow``."""
    c = acl.config()
    subjects = {s["id"] for s in c["subjects"] if identity in s["cert_common_names"]}
    rules: dict[str, Any] = {r["id"]: r for r in c["rules"]}
    out: set[str] = set()
    for policy in c["policies"]:
        if not subjects & set(policy["subjects"]):
            continue
        for rid in policy["rules"]:
            r = rules[rid]
            if message in r["messages"] and flow in r["flows"]:
                out |= set(r["key_exprs"])
    return out


def test_the_planners_may_ask_the_ews_for_forecasts_and_nothing_else() -> None:
    key = "dualpilot/*/ews/forecasts"
    for planner in ("system1", "system2"):
        assert allowed(planner, "query", "ingress") == {key}
    for other in ("uavsim", "monitor", "ews"):
        assert key not in allowed(other, "query", "ingress")
    assert key not in allowed("supervisor", "query", "ingress")


def test_only_the_ews_answers_forecasts() -> None:
    key = "dualpilot/*/ews/forecasts"
    answerers = [who for who in ("ews", "system1", "system2", "supervisor", "uavsim")
                 if key in allowed(who, "declare_queryable", "ingress")]
    assert answerers == ["ews"], answerers
