"""The warm server's forked process becoming the client's command.

Forked from the server (:mod:`cnc_twin.server.daemon`), it takes on everything a new interpreter
would have had from the client (:mod:`cnc_twin.core.server_link`): the client's stdin, stdout
and stderr, working directory, environment, umask and (lowered only) resource limits; a process
group of its own (the client forwards the terminal's signals to it); the start handlers of
:mod:`cnc_twin.entry`. Then it runs :func:`cnc_twin.cli.main` as the program would and ends with
its status; helpers it starts are forks of it (:data:`cnc_twin.core.helpers.FORK`).
"""

from __future__ import annotations

import io
import os
import resource
import signal
import sys
import traceback


def become_command(request: dict, fds: list[int], close: list[int],
                   spares: dict[str, tuple[int, int, int, int]]) -> None:  # pragma: no cover - in the fork
    """Run the command of ``request`` (see :func:`cnc_twin.core.server_link._hand_over`) with the
    descriptors ``fds`` (the client's stdin, stdout, stderr) after closing the server's own
    ``close``, with the helpers the server started ahead (:data:`cnc_twin.core.helpers.SPARES`);
    never returns."""
    code = 1
    try:
        for fd in close:
            os.close(fd)
        os.setpgid(0, 0)
        for target, fd in enumerate(fds):
            os.dup2(fd, target)
        for fd in fds:
            if fd > 2:
                os.close(fd)
        _take_on(request)
        from cnc_twin import entry
        from cnc_twin.core import helpers
        from cnc_twin.core.phases import mark

        entry.install_start_handlers()
        helpers.FORK = True
        helpers.SPARES.update(spares)
        mark("forked")
        from cnc_twin.cli import main

        code = main()
    except SystemExit as exc:  # argparse's usage errors, as the program would end
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except BaseException:
        traceback.print_exc()
        code = 1
    finally:
        from cnc_twin.core.helpers import exit_fork

        exit_fork(code)


def _take_on(request: dict) -> None:
    """The client's directory, environment, umask, limits, signals and standard streams."""
    os.chdir(request["cwd"])
    os.umask(request["umask"])
    os.environ.clear()
    os.environ.update(request["env"])
    os.environ.setdefault("MUJOCO_GL", "disable")  # as cnc_twin's import sets it
    for limit, (soft, hard) in request["rlimits"].items():
        have_soft, have_hard = resource.getrlimit(limit)
        hard = _lower(hard, have_hard)
        soft = _lower(_lower(soft, have_soft), hard)
        if (soft, hard) != (have_soft, have_hard):
            resource.setrlimit(limit, (soft, hard))
    signal.set_wakeup_fd(-1)
    for signum in (signal.SIGCHLD, signal.SIGHUP, signal.SIGQUIT, signal.SIGUSR1, signal.SIGUSR2):
        signal.signal(signum, signal.SIG_DFL)
    unbuffered = bool(os.environ.get("PYTHONUNBUFFERED"))
    sys.stdin = io.TextIOWrapper(io.open(0, "rb", closefd=False), encoding=sys.__stdin__.encoding,
                                 errors=sys.__stdin__.errors)
    sys.stdout = io.TextIOWrapper(io.open(1, "wb", closefd=False), encoding=sys.__stdout__.encoding,
                                  errors=sys.__stdout__.errors, line_buffering=os.isatty(1), write_through=unbuffered)
    sys.stderr = io.TextIOWrapper(io.open(2, "wb", closefd=False), encoding=sys.__stderr__.encoding,
                                  errors="backslashreplace", line_buffering=True, write_through=unbuffered)
    sys.argv = ["cnc-twin", *request["argv"]]


def _lower(want: int, have: int) -> int:
    """The lower of two resource limits (``RLIM_INFINITY`` the highest)."""
    if want == resource.RLIM_INFINITY:
        return have
    if have == resource.RLIM_INFINITY:
        return want
    return min(want, have)
