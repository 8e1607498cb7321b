"""Services started from a warm fork server instead of fresh interpreters (the e2e tier's).

A service started with ``python -m services.<name>`` spends most of a second of CPU before
it serves: the interpreter, its imports (numpy, scipy, protobuf, OMPL, Zenoh) and the Numba
kernels loaded from the disk cache and warmed. The e2e tier starts over five hundred
service processes (docs/testing.md). After :func:`enable`,
:class:`services.launch.processes.ProcessGroup` starts a command of the form
``<this python> -m <module> [args]`` as a child of the standard library's fork server
(``multiprocessing``'s "forkserver" context): one server per launcher process, which
imported :data:`PRELOAD` once (the services' compute-thread limits, then every service's
modules, their kernels warmed) and forks a copy of itself per service. The copy becomes
what ``python -m <module> args`` would be (:func:`serve`): the launcher's ignored signals
ignored and the others at their defaults; a session of its own; the given
environment, working directory and argv; standard input from /dev/null, standard output
and error appended to the log file (unbuffered under ``PYTHONUNBUFFERED``); the module run
as ``__main__`` (:func:`runpy.run_module`); and on exit what the interpreter does:
non-daemon threads joined (idle executors stopped first), ``atexit`` handlers run, the
status of ``SystemExit`` (1 and a traceback for an uncaught exception, death by SIGINT for an
uncaught KeyboardInterrupt).

What differs from a fresh interpreter: the modules the server imported were imported under
its environment (of what they read at import, BLAS's thread limits are taken from the
compose file and MAVLink's ``MAVLINK20`` is 1 in both); ``/proc/<pid>/cmdline`` is the
server's; the process is the server's child, not the launcher's (its exit status reaches
the launcher through the server). A program that calls :func:`enable` must guard its own
main (``if __name__ == "__main__"``): multiprocessing has each forked child import the
program's main module (pytest's is guarded; an xdist worker's has no file).
``make run``, ``services.launch``, compose and the integration tier start services as fresh
interpreters.
"""

from __future__ import annotations

import atexit
import contextlib
import io
import multiprocessing
import os
import runpy
import signal
import subprocess
import sys
import threading
import traceback
from collections.abc import Mapping, Sequence
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Any

#: the modules the fork server imports, in order, before it forks anything
PRELOAD = ("services.forking.threads", "services.forking.warm")

#: the signals whose "ignored" a child inherits through exec, which a forked service takes
#: from its launcher (else the default, and Python's KeyboardInterrupt for SIGINT)
INHERITED_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGQUIT, signal.SIGHUP)

_context: multiprocessing.context.ForkServerContext | None = None
_stop_registered = False


def enable(preload: Sequence[str] = PRELOAD) -> None:
    """Start services from the fork server from now on in this process (the server itself
    starts with the first service, importing ``preload``, and is stopped when this process
    exits: :func:`stop`)."""
    global _context, _stop_registered
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(preload))
    if not _stop_registered:
        atexit.register(stop)
        _stop_registered = True
    _context = ctx


def stop() -> None:
    """Stop the fork server and wait for it (a no-op when it is not running): it would end
    with this process anyway, but unwaited for, and the CPU time of the services it waited
    for would be counted nowhere (``time make test``)."""
    from multiprocessing import forkserver

    with contextlib.suppress(Exception):  # the standard library's own stop, private in 3.11
        forkserver._forkserver._stop()  # type: ignore[attr-defined]


def disable() -> None:
    """Start services as fresh interpreters again (the server, if started, stays up)."""
    global _context
    _context = None


def module_of(argv: Sequence[str]) -> str | None:
    """The module of ``<this python> -m <module> ...`` (None: another command)."""
    if len(argv) >= 3 and argv[0] == sys.executable and argv[1] == "-m":
        return argv[2]
    return None


class ForkedProcess:
    """A service the fork server started: the part of :class:`subprocess.Popen` the launcher
    uses (``pid``, ``args``, ``returncode``, ``poll``, ``wait``)."""

    def __init__(self, process: BaseProcess, args: Sequence[str]) -> None:
        self._process = process
        self.args = list(args)

    @property
    def pid(self) -> int:
        return int(self._process.pid or 0)

    @property
    def returncode(self) -> int | Any:  # None while it runs: typed as typeshed types Popen's
        return self._process.exitcode

    def poll(self) -> int | None:
        return self._process.exitcode

    def wait(self, timeout: float | None = None) -> int:
        self._process.join(timeout)
        code = self._process.exitcode
        if code is None:
            raise subprocess.TimeoutExpired(self.args, timeout or 0.0)
        return code


def start(argv: Sequence[str], env: Mapping[str, str], cwd: Path,
          log_path: Path) -> ForkedProcess | None:
    """Fork ``argv`` (``<this python> -m <module> ...``) from the fork server, its output
    appended to ``log_path``; None when forking is off or ``argv`` is another command."""
    module = module_of(argv)
    if _context is None or module is None:
        return None
    ignored = [int(sig) for sig in INHERITED_SIGNALS if signal.getsignal(sig) is signal.SIG_IGN]
    process = _context.Process(target=serve, name=module,
                               args=(module, list(argv[3:]), dict(env), str(cwd),
                                     str(log_path), ignored))
    process.start()
    return ForkedProcess(process, argv)


def _stream(fd: int, unbuffered: bool) -> io.TextIOWrapper:
    raw = open(fd, "wb", buffering=0, closefd=False)  # noqa: SIM115 (the process's own stream)
    return io.TextIOWrapper(raw if unbuffered else io.BufferedWriter(raw), encoding="utf-8",
                            errors="backslashreplace", line_buffering=True,
                            write_through=unbuffered)


def serve(module: str, args: list[str], env: dict[str, str], cwd: str, log_path: str,
          ignored: list[int]) -> None:
    """In the forked child: become ``python -m module args`` and run it (module docstring);
    ``ignored``: the signals the launcher ignored when it asked (an exec'd child would
    inherit that). Never returns."""
    for sig in INHERITED_SIGNALS:  # as exec leaves them: ignored stays ignored, else default
        default = signal.default_int_handler if sig == signal.SIGINT else signal.SIG_DFL
        signal.signal(sig, signal.SIG_IGN if int(sig) in ignored else default)
    os.setsid()
    fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    null = os.open(os.devnull, os.O_RDONLY)
    os.dup2(null, 0)
    os.close(null)
    unbuffered = bool(env.get("PYTHONUNBUFFERED"))
    sys.stdout, sys.stderr = _stream(1, unbuffered), _stream(2, unbuffered)
    sys.stdin = open(0, closefd=False)  # noqa: SIM115
    os.chdir(cwd)
    os.environ.clear()
    os.environ.update(env)
    if cwd not in sys.path:
        sys.path.insert(0, cwd)  # as ``python -m`` puts the working directory first
    sys.argv = [module, *args]
    code, interrupted = 0, False
    try:
        runpy.run_module(module, run_name="__main__", alter_sys=True)
    except SystemExit as err:
        if err.code is None or isinstance(err.code, int):
            code = int(err.code or 0)
        else:
            print(err.code, file=sys.stderr)
            code = 1
    except KeyboardInterrupt:
        interrupted = True
        traceback.print_exc()
    except BaseException:
        traceback.print_exc()
        code = 1
    _exit(code, interrupted)


def _exit(code: int, interrupted: bool) -> None:
    """End as the interpreter would (``Py_FinalizeEx``): ``threading._shutdown`` (the
    threading module's exit hooks, which stop idle executors' workers, then every non-daemon
    thread joined), ``atexit`` run, streams flushed; an uncaught KeyboardInterrupt dies by
    SIGINT."""
    threading._shutdown()  # type: ignore[attr-defined]  # as multiprocessing's own children do
    try:
        atexit._run_exitfuncs()
    finally:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):  # a closed stream: nothing more to write
                stream.flush()
        if interrupted:
            signal.signal(signal.SIGINT, signal.SIG_DFL)
            os.kill(os.getpid(), signal.SIGINT)
        os._exit(code)
