#!/bin/sh
# The headless browser of tests/e2e/test_web_view.py: Debian's chromium, driven by playwright
# (pinned in the dev extra) through its executable_path; playwright's own browser downloads are
# never used. Run by `make test` and `make browser` (a no-op when /usr/bin/chromium is there);
# installing needs root and apt (a fresh Debian machine, CI).
set -eu
BROWSER=${BROWSER:-/usr/bin/chromium}
if [ -x "$BROWSER" ]; then
    exit 0
fi
if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null 2>&1; then
    echo "install_browser: $BROWSER is missing; as root on Debian: apt-get install chromium" >&2
    exit 1
fi
echo "install_browser: apt-get install chromium (once)"
apt-get update -qq
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
"$BROWSER" --version
