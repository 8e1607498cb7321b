"""The router's access control with TLS on (``ZENOH_TLS_DIR``): who may say what, by certificate.

Zenoh's access control (``access_control`` in the router's config) filters
the messages crossing the router's interfaces, matching each remote session
by the common name of the certificate it presented (mutual TLS, the CA of
``python -m services.certs``). The default is deny; what is allowed:

- **ingress**, by owner: a service may publish, declare a queryable, reply
  and declare liveliness tokens only on its own keys (:data:`OWNED`): the
  planners ``plan/system1`` and ``plan/system2`` (and a replica's own
  ``plan/system<k>/<zid>``), the EWS ``ews/*``, the
  supervisor its decision, state, event, clock and operator waypoints, and
  every service its ``status/<service>`` and ``alive/<service>`` tokens;
  only the supervisor may query (plans, the EWS, statuses), and the planners the forecasts
  the EWS answered it (``ews/forecasts``: a plan request's forecast by reference).
- **ingress**, for every identity of the CA (the services and ``monitor``,
  the launcher's read-only observer): declaring subscribers, liveliness
  subscribers and liveliness queries under ``dualpilot/**``.
- **egress**: everything under ``dualpilot/**`` to every identity: what the
  router forwards has already been admitted on its way in (a put by its
  owner, a query by the supervisor, a reply by the queryable's owner).

This holds only for traffic through the router: with TLS on every service
is a Zenoh **client** (bus.zenoh_config), so there are no direct peer links
whose traffic the router never sees. The uav id is a wildcard: the
credentials name a service, not a vehicle.
"""

from __future__ import annotations

from typing import Any

#: the identities that may talk at all (the certificates' common names)
EVERYONE = ("ews", "system1", "system2", "supervisor", "uavsim", "monitor")

_NS = "dualpilot/*"

#: the keys (under ``dualpilot/<uav>/``) each service publishes on or answers
OWNED: dict[str, dict[str, tuple[str, ...]]] = {
    "ews": {"put": ("ews/fires", "ews/forecast"), "answer": ("ews/command", "ews/forecasts")},
    "system1": {"put": (), "answer": ("plan/system1", "plan/system1/*")},
    "system2": {"put": (), "answer": ("plan/system2", "plan/system2/*")},
    "supervisor": {"put": ("supervisor/decision", "vehicle/state", "mission/event", "clock",
                           "operator/waypoints"), "answer": ()},
    "uavsim": {"put": (), "answer": ("uavsim/mission", "uavsim/flight")},
}
#: what the supervisor asks
QUERIES = ("plan/*", "plan/*/*", "ews/command", "status/*", "uavsim/mission",
           "uavsim/flight")
#: what the planners ask: the forecasts a plan request names by reference
PLANNER_QUERIES = ("ews/forecasts",)
PLANNERS = ("system1", "system2")


def _rule(rid: str, messages: list[str], keys: list[str], flows: list[str]) -> dict[str, Any]:
    return {"id": rid, "permission": "allow", "flows": flows, "messages": messages,
            "key_exprs": keys}


def config() -> dict[str, Any]:
    """The ``access_control`` section of the router's config."""
    rules = [
        _rule("egress", ["put", "delete", "query", "reply", "declare_subscriber",
                         "declare_queryable", "liveliness_token",
                         "declare_liveliness_subscriber", "liveliness_query"],
              ["dualpilot/**"], ["egress"]),
        _rule("listen", ["declare_subscriber", "declare_liveliness_subscriber",
                         "liveliness_query"], ["dualpilot/**"], ["ingress"]),
        _rule("supervisor-asks", ["query"], [f"{_NS}/{k}" for k in QUERIES], ["ingress"]),
        _rule("planners-ask", ["query"], [f"{_NS}/{k}" for k in PLANNER_QUERIES], ["ingress"]),
    ]
    subjects = [{"id": "everyone", "cert_common_names": list(EVERYONE)}]
    policies = [{"id": "everyone", "rules": ["egress", "listen"], "subjects": ["everyone"]},
                {"id": "supervisor-asks", "rules": ["supervisor-asks"],
                 "subjects": ["supervisor"]},
                {"id": "planners-ask", "rules": ["planners-ask"], "subjects": list(PLANNERS)}]
    for name, owned in OWNED.items():
        subjects.append({"id": name, "cert_common_names": [name]})
        alive = [f"{_NS}/alive/{name}", f"{_NS}/alive/{name}/*"]
        rules.append(_rule(f"{name}-alive", ["liveliness_token"], alive, ["ingress"]))
        answers = [f"{_NS}/{k}" for k in (*owned["answer"], f"status/{name}")]
        rules.append(_rule(f"{name}-answers", ["declare_queryable", "reply"], answers,
                           ["ingress"]))
        own = [f"{name}-alive", f"{name}-answers"]
        if owned["put"]:
            rules.append(_rule(f"{name}-puts", ["put", "delete"],
                               [f"{_NS}/{k}" for k in owned["put"]], ["ingress"]))
            own.append(f"{name}-puts")
        policies.append({"id": name, "rules": own, "subjects": [name]})
    return {"enabled": True, "default_permission": "deny", "rules": rules,
            "subjects": subjects, "policies": policies}
