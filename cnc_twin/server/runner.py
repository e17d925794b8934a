"""The warm server's forked process becoming the client's command.

Forked from the server (:mod:`cnc_twin.server.daemon`), it takes on everything a new interpreter
would have had from the client (:mod:`cnc_twin.core.server_link`): the client's stdin, stdout
and stderr, working directory, environment, umask and (lowered only) resource limits; a process
group of its own (the client forwards the terminal's signals to it); the start handlers of
:mod:`cnc_twin.entry`. Then it runs :func:`cnc_twin.cli.main` as the program would and ends with
its status; helpers it starts are forks of it (:data:`cnc_twin.core.helpers.FORK`).
"""

from __future__ import annotations

import os
import resource
import sys


def become_command(request: dict, fds: list[int], close: list[int],
                   spares: dict[str, tuple[int, int, int, int]]) -> None:  # pragma: no cover - in the fork
    """Run the command of ``request`` (see ``cnc_twin.core.server_link._hand_over``) with the
    descriptors ``fds`` (the client's stdin, stdout, stderr) after closing the server's own
    ``close``, with the helpers the server started ahead (:data:`cnc_twin.core.helpers.SPARES`);
    never returns."""
    from cnc_twin.core import helpers

    def command() -> int:
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
        from cnc_twin.core.phases import mark

        entry.install_start_handlers()
        helpers.FORK = True
        helpers.SPARES.update(spares)
        mark("forked")
        from cnc_twin.cli import main

        return main()

    helpers.exit_as_program(command)


def _take_on(request: dict) -> None:
    """The client's directory, environment, umask, limits, signals and standard streams."""
    from cnc_twin.core.helpers import as_new_interpreter

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
    as_new_interpreter()  # after the environment: PYTHONUNBUFFERED is the caller's
    sys.argv = ["cnc-twin", *request["argv"]]


def _lower(want: int, have: int) -> int:
    """The lower of two resource limits (``RLIM_INFINITY`` the highest)."""
    if want == resource.RLIM_INFINITY:
        return have
    if have == resource.RLIM_INFINITY:
        return want
    return min(want, have)
