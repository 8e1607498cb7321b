"""A program that reports how it was started: ``python -m tests.support.forkprobe ACTION``.

It prints one JSON line (its argv, working directory, ``PROBE_*`` and a few other
environment names, session and group ids, whether standard input is /dev/null, whether it
is ``__main__``) and then does ACTION: ``exit3`` (SystemExit(3)), ``raise`` (an uncaught
RuntimeError), ``sigint`` (waits for SIGINT, uncaught), ``clean-sigint`` (waits for SIGINT,
caught: exit 0), ``atexit`` (an atexit handler and a non-daemon thread print after main
returns), ``executor`` (a thread-pool executor left idle, not shut down), ``heap`` (prints
how many objects the collector holds frozen, ``gc.get_freeze_count()``), anything else:
exit 0. tests/integration/test_forking.py runs it as a fresh
interpreter and from the fork server and compares.
"""

from __future__ import annotations

import atexit
import gc
import json
import os
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor

POOLS: list[ThreadPoolExecutor] = []


def report() -> dict[str, object]:
    null = os.stat(os.devnull)
    stdin = os.fstat(0)
    return {
        "argv": sys.argv[1:], "argv0": os.path.basename(sys.argv[0]), "cwd": os.getcwd(),
        "env": {k: v for k, v in os.environ.items() if k.startswith("PROBE_")},
        "has_home": "HOME" in os.environ, "own_session": os.getsid(0) == os.getpid(),
        "own_group": os.getpgid(0) == os.getpid(),
        "stdin_null": (stdin.st_dev, stdin.st_ino) == (null.st_dev, null.st_ino),
        "main": __name__ == "__main__",
    }


def main() -> None:
    print(json.dumps(report()), flush=True)
    action = sys.argv[1] if len(sys.argv) > 1 else ""
    if action == "exit3":
        sys.exit(3)
    if action == "raise":
        raise RuntimeError("the probe's uncaught error")
    if action == "sigint":
        while True:
            time.sleep(0.05)
    if action == "clean-sigint":
        try:
            while True:
                time.sleep(0.05)
        except KeyboardInterrupt:
            print("interrupted", flush=True)
            return
    if action == "executor":
        POOLS.append(ThreadPoolExecutor(max_workers=1))  # kept: only the exit may stop it
        print(POOLS[0].submit(lambda: "task ran").result(), flush=True)
    if action == "heap":
        print(json.dumps({"frozen": gc.get_freeze_count()}), flush=True)
    if action == "atexit":
        atexit.register(lambda: print("atexit ran", flush=True))

        def late() -> None:
            time.sleep(0.3)
            print("thread finished", flush=True)

        threading.Thread(target=late).start()


if __name__ == "__main__":
    main()
