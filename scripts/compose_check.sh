#!/usr/bin/env bash
# make compose-check: `docker compose up` for real, on a machine with apt and no Docker engine.
#
# 1. installs docker.io, docker-compose (v1.29 in bookworm) and debootstrap if missing;
# 2. starts dockerd --iptables=false --bridge=none (as root) unless an engine already answers;
# 3. builds a local base image where no registry is reachable: debootstrap --variant=minbase
#    bookworm (python3, venv, pip) piped through tar into `docker import` (the host's CA bundle
#    goes in, so pip inside the build trusts the same TLS roots as the host's pip);
# 4. builds the project's image on it (ARG BASE_IMAGE), flies the default mission (the one
#    `make run` flies; CONTROLLER, MISSION_SEED and TIMING are unset for it) with
#    docker-compose.yml + docker-compose.router.yml (the project's own router: eclipse/zenoh
#    cannot be pulled) and the viewer profile, `--exit-code-from supervisor`, fetches the live
#    view's web page and its scripts through the published port 8766 while the mission flies,
#    and checks that it reached the goal: exit code 0 and runs/compose/summary.json's ending;
# 5. takes the stack down and stops the daemon it started (and only that one).
#
# Settings (environment): BASE_IMAGE (skip step 3 and use this image), KEEP_BASE=1 (reuse a
# base image built before), MIRROR (Debian mirror for debootstrap), COMPOSE (compose command),
# REF (build and fly a git commit, e.g. REF=HEAD, instead of the working tree: uncommitted
# edits elsewhere in a shared tree then cannot break the check).
set -euo pipefail

cd "$(dirname "$0")/.."
T0=$(date +%s)
WORK=$(mktemp -d /tmp/compose-check.XXXXXX)
if [ -n "${REF:-}" ]; then
    mkdir "$WORK/src"
    git archive "$REF" | tar -x -C "$WORK/src"
    cd "$WORK/src"
fi
BASE_TAG=dualpilot-base:bookworm
MIRROR=${MIRROR:-http://deb.debian.org/debian}
PROJECT=dualpilot-check
DAEMON_PID=""

say() { echo "[compose-check +$(( $(date +%s) - T0 ))s] $*"; }

cleanup() {
    local rc=$?
    if [ -n "${COMPOSE_CMD:-}" ] && [ -S /var/run/docker.sock ]; then
        $COMPOSE_CMD down --remove-orphans >/dev/null 2>&1 || true
    fi
    if [ -n "$DAEMON_PID" ]; then
        say "stopping dockerd (pid $DAEMON_PID)"
        kill "$DAEMON_PID" 2>/dev/null || true
        for _ in $(seq 1 30); do kill -0 "$DAEMON_PID" 2>/dev/null || break; sleep 1; done
        kill -9 "$DAEMON_PID" 2>/dev/null || true
    fi
    rm -rf "$WORK"
    say "done (exit $rc), wall time $(( $(date +%s) - T0 )) s"
    exit $rc
}
trap cleanup EXIT

if [ "$(id -u)" != 0 ]; then
    echo "compose-check needs root (it installs packages and starts dockerd)" >&2
    exit 2
fi

# -- 1. packages ------------------------------------------------------------------------------
if ! command -v dockerd >/dev/null || ! command -v docker-compose >/dev/null \
        || ! command -v debootstrap >/dev/null; then
    say "installing docker.io docker-compose debootstrap"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
        docker.io docker-compose debootstrap ca-certificates >/dev/null
fi
# Debian's client matches Debian's daemon (a newer CLI elsewhere on PATH wants buildx)
DOCKER=/usr/bin/docker
[ -x "$DOCKER" ] || DOCKER=$(command -v docker)
export DOCKER_BUILDKIT=0

# -- 2. daemon ----------------------------------------------------------------------------------
if ! "$DOCKER" info >/dev/null 2>&1; then
    say "starting dockerd --iptables=false --bridge=none"
    dockerd --iptables=false --bridge=none >"$WORK/dockerd.log" 2>&1 &
    DAEMON_PID=$!
    for _ in $(seq 1 60); do "$DOCKER" info >/dev/null 2>&1 && break; sleep 1; done
    "$DOCKER" info >/dev/null 2>&1 || { tail -20 "$WORK/dockerd.log" >&2; exit 1; }
fi
say "engine: $("$DOCKER" version --format '{{.Server.Version}}'), storage $("$DOCKER" info --format '{{.Driver}}')"

# -- 3. base image --------------------------------------------------------------------------------
if [ -z "${BASE_IMAGE:-}" ]; then
    BASE_IMAGE=$BASE_TAG
    if [ "${KEEP_BASE:-0}" = 1 ] && "$DOCKER" image inspect "$BASE_TAG" >/dev/null 2>&1; then
        say "reusing $BASE_TAG"
    else
        say "debootstrap --variant=minbase bookworm"
        ROOT="$WORK/rootfs"
        debootstrap --variant=minbase \
            --include=python3,python3-venv,python-is-python3,ca-certificates \
            bookworm "$ROOT" "$MIRROR" >"$WORK/debootstrap.log" 2>&1 \
            || { tail -20 "$WORK/debootstrap.log" >&2; exit 1; }
        cp /etc/ssl/certs/ca-certificates.crt "$ROOT/etc/ssl/certs/ca-certificates.crt"
        chroot "$ROOT" python3 -m venv /opt/venv
        rm -rf "$ROOT/var/lib/apt/lists/"* "$ROOT/var/cache/apt/"*.bin
        say "docker import $BASE_TAG"
        tar -C "$ROOT" -c . | "$DOCKER" import \
            --change 'ENV PATH=/opt/venv/bin:/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin' \
            --change 'ENV PIP_CERT=/etc/ssl/certs/ca-certificates.crt' \
            --change 'CMD ["python3"]' - "$BASE_TAG" >/dev/null
        rm -rf "$ROOT"
    fi
fi
export BASE_IMAGE

# -- 4. image, one mission --------------------------------------------------------------------------
say "docker build (BASE_IMAGE=$BASE_IMAGE)"
B0=$(date +%s)
"$DOCKER" build --network host --build-arg BASE_IMAGE="$BASE_IMAGE" -t dualpilot:0.1.0 . \
    >"$WORK/build.log" 2>&1 || { tail -30 "$WORK/build.log" >&2; exit 1; }
say "image built in $(( $(date +%s) - B0 )) s: $("$DOCKER" image inspect dualpilot:0.1.0 --format '{{.Size}}') bytes"

unset CONTROLLER MISSION_SEED TIMING  # the default mission: a newcomer's first `up`
COMPOSE_CMD="${COMPOSE:-docker-compose} -p $PROJECT -f docker-compose.yml -f docker-compose.router.yml"
SUMMARY=runs/compose/summary.json
rm -f "$SUMMARY"
say "$COMPOSE_CMD --profile viewer up --no-build --exit-code-from supervisor"
M0=$(date +%s)
set +e
$COMPOSE_CMD --profile viewer up --no-build --exit-code-from supervisor >"$WORK/up.log" 2>&1 &
UP_PID=$!
# the live view's web page, through the published port while the mission flies: the page and
# the BokehJS it names, both from the viewer's container (no CDN)
python3 - "${WEB_URL:-http://127.0.0.1:8766/}" >"$WORK/web.log" 2>&1 <<'EOF_WEB' &
import re, sys, time, urllib.request
url, deadline = sys.argv[1], time.monotonic() + 120
while True:
    try:
        page = urllib.request.urlopen(url, timeout=5).read().decode()
        break
    except OSError as err:
        if time.monotonic() > deadline:
            sys.exit(f"web page: nothing at {url} ({err})")
        time.sleep(1)
scripts = re.findall(r'src="(/static/js/[^"?]+)', page)
assert "/static/js/bokeh.min.js" in scripts, page[:500]
for path in scripts:
    body = urllib.request.urlopen(url.rstrip("/") + path, timeout=5).read()
    assert len(body) > 1000, path
print(f"web page: {url} served, {len(page)} bytes, {len(scripts)} scripts from the viewer "
      f"({', '.join(p.rsplit('/', 1)[1] for p in scripts)})")
EOF_WEB
WEB_PID=$!
wait "$UP_PID"
UP_RC=$?
wait "$WEB_PID"
WEB_RC=$?
set -e
say "mission stack exited with $UP_RC after $(( $(date +%s) - M0 )) s"
cat "$WORK/web.log"
grep -h '"summary"' "$WORK/up.log" | tail -1 || true
# 0: the mission reached G, as the default mission does. 3 (it ended in a failure, a fire) or
# anything else (1: aborted, a service died) fails the check.
if [ "$UP_RC" != 0 ]; then tail -40 "$WORK/up.log" >&2; exit 1; fi
if [ "$WEB_RC" != 0 ]; then grep viewer "$WORK/up.log" | tail -20 >&2; exit 1; fi
python3 - "$SUMMARY" <<'EOF'
import json, sys
s = json.load(open(sys.argv[1]))
print(f"summary.json: seed={s['seed']} success={s['success']} ending={s.get('ending')} "
      f"steps={s['steps']} mission_time_s={s['mission_time_s']}")
assert s["steps"] > 0 and s["success"] is True and s["ending"] == "goal", s
assert "failure_cause" not in s, s  # a success has no cause
EOF
say "compose-check passed"
