"""The warm server: a process that has loaded the twin once and forks a process per command.

``python -m cnc_twin.server.daemon KEY`` (started by :func:`cnc_twin.core.server_link.start_server`,
detached; warming up once the command that started it has ended). It takes the lock of its key (a second server of the same key ends at once),
imports what the commands use (numpy, MuJoCo, numba's compiled-code target, scipy's splines,
Arrow, the G-code reader, the planner's modules; not rerun, whose threads a fork would not keep)
and loads the twin's compiled kernels by building the twins of
:data:`~cnc_twin.studies.kernel_warmup.WARMUP_SCENARIOS`. Only then does it listen (the socket
appears when the server is ready), and it asks older servers of the installation to end.

It serves one byte at the start of each connection: ``c`` with the client's three descriptors,
then the command (it forks the process that becomes it, :mod:`cnc_twin.server.runner`, answers
``{"pid": ...}``, and ``{"status": wait status}`` when it has ended; a client that goes away
first has its command ended as SIGTERM ends it, the run directory written); ``?`` asks its state;
``s`` asks it to stop (it stops taking commands at once and ends when those running have ended).
A server with nothing to do for :data:`~cnc_twin.core.server_link.IDLE_SECONDS` ends too, as does
one whose socket was taken away. Nothing of a command runs in the server itself: every command
starts from the same loaded state, and lockstep runs give the traces they give without it.
"""

from __future__ import annotations

import contextlib
import io
import os
import select
import selectors
import signal
import socket
import sys
import time
import warnings
from pathlib import Path

from cnc_twin.core import server_link

SPARE_RECORDING = "cnc_twin.view.rerun_stream"
"""the helper kept started ahead: the recording process, whose rerun import (0.4 - 1 s of CPU) would
otherwise run beside the command's run"""

ACCEPT_TIMEOUT = 5.0
"""how long a connection may take to say what it wants [s]"""


def warm_up() -> None:
    """Import what the commands use and load the twin's compiled kernels (see the module's text)."""
    import numba.core.registry
    import matplotlib.backends.backend_agg  # noqa: F401 - the run directory's pictures
    import matplotlib.figure  # noqa: F401
    import pyarrow.parquet  # noqa: F401 - the trace

    import cnc_twin.cli  # noqa: F401
    import cnc_twin.planner.process  # noqa: F401 - its forks plan without importing
    import cnc_twin.run.result  # noqa: F401
    import cnc_twin.run.run_dir  # noqa: F401
    import cnc_twin.run.summary  # noqa: F401
    import cnc_twin.server.runner  # noqa: F401 - what each fork becomes
    import cnc_twin.trace.parquet  # noqa: F401
    import cnc_twin.view.rerun_stream  # noqa: F401 - the command's side (rerun itself: in its process)
    from cnc_twin.run.progress import ProgressBar  # noqa: F401
    from cnc_twin.core import disk_cache
    from cnc_twin.run.twin import Twin
    from cnc_twin.scenario.load import load_scenario
    from cnc_twin.scenario.resources import scenarios_dir
    from cnc_twin.studies.kernel_warmup import WARMUP_SCENARIOS

    numba.core.registry.cpu_target.target_context.refresh()
    disk_cache.code_digest()  # the caches' keys: worked out once here, not in every command
    for name in (*WARMUP_SCENARIOS, "gcode_cam_raster.yaml", "freeform_polish.yaml"):
        try:
            twin = Twin(load_scenario(scenarios_dir() / name))
        except Exception:  # a bundled scenario that cannot load is the tests' to find, not the server's
            continue
        twin.load_kernels()
        if twin.removal is not None:
            twin.removal.model_removal.save_picture(io.BytesIO())  # matplotlib's first drawing loads its fonts
    import gc

    gc.collect()
    gc.freeze()  # what every command shares stays shared: no collection touches its pages


class Server:
    """The listening socket, the commands' connections and processes (see the module's text)."""

    def __init__(self, key: str, listener: socket.socket, path: Path):
        self.key, self.listener, self.path = key, listener, path
        self.inode = path.stat().st_ino
        self.selector = selectors.DefaultSelector()
        self.selector.register(listener, selectors.EVENT_READ, ("accept", None))
        self.commands: dict[int, tuple[socket.socket, int]] = {}
        """runner pid -> (its client's connection, its pidfd)"""
        self.spare = None
        """the recording process started ahead for the next command (rerun imported), or None"""
        self._make_spare()
        self.started = time.time()
        self.served = 0
        self.stopping = False
        self.last_activity = time.monotonic()

    def serve(self) -> None:
        while self.commands or not self.stopping:
            if not self.commands and not self.stopping:
                if time.monotonic() - self.last_activity > server_link.IDLE_SECONDS or not self._socket_is_ours():
                    self._stop_listening()
            for event, _ in self.selector.select(timeout=10.0):
                what, data = event.data
                if what == "accept":
                    self._accept()
                elif what == "ended":
                    self._ended(data)
                elif what == "client":
                    self._client_spoke(data)
                elif what == "reap":
                    self.selector.unregister(event.fd)
                    data.poll()
            if not self.commands and not self.stopping:
                self._make_spare()
        self.selector.close()

    def _make_spare(self) -> None:
        """A recording process for the next command, if none is waiting: forked from this server,
        it imports rerun now, while nothing runs, instead of beside the next run."""
        if self.spare is not None:
            if self.spare.poll() is None:
                return
            self.spare_stderr.close()  # a spare that died: its file goes with it
        import tempfile

        from cnc_twin.core.helpers import ForkedHelper

        self.spare_stderr = tempfile.TemporaryFile()  # its last words, should it fail, for its command
        try:
            self.spare = ForkedHelper(SPARE_RECORDING, [], stderr=self.spare_stderr, spare=True)
        except OSError:  # no process to spare now: the next command starts its own
            self.spare = None
            self.spare_stderr.close()

    def _hand_spare(self) -> dict[str, tuple[int, int, int, int]]:
        """The spare for the command about to be forked (see :data:`cnc_twin.core.helpers.SPARES`)."""
        if self.spare is None or self.spare.poll() is not None:
            return {}
        spare = self.spare
        return {SPARE_RECORDING: (spare.pid, spare.stdin.fileno(), spare.stdout.fileno(), self.spare_stderr.fileno())}

    def _let_spare_go(self) -> None:
        """After the fork: the command has the spare; this server only reaps it when it ends."""
        spare, self.spare = self.spare, None
        spare.stdin.close()
        spare.stdout.close()
        self.spare_stderr.close()
        if spare.pidfd is not None:
            self.selector.register(spare.pidfd, selectors.EVENT_READ, ("reap", spare))

    def _socket_is_ours(self) -> bool:
        try:
            return self.path.stat().st_ino == self.inode
        except OSError:
            return False

    def _stop_listening(self) -> None:
        if not self.stopping:
            self.stopping = True
            self.selector.unregister(self.listener)
            if self._socket_is_ours():
                self.path.unlink(missing_ok=True)
            self.listener.close()

    def _accept(self) -> None:
        try:
            conn, _ = self.listener.accept()
        except OSError:
            return
        self.last_activity = time.monotonic()
        try:
            conn.settimeout(ACCEPT_TIMEOUT)
            uid = conn.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, 12)[4:8]
            if int.from_bytes(uid, sys.byteorder) != os.getuid():
                conn.close()
                return
            tag, fds, _, _ = socket.recv_fds(conn, 1, 3)
            if tag == b"c" and len(fds) == 3:
                request = server_link.receive_message(conn)
                if isinstance(request, dict):
                    self._start_command(conn, request, fds)
                    return
            for fd in fds:
                os.close(fd)
            if tag == b"?":
                server_link.send_message(conn, {"pid": os.getpid(), "key": self.key, "started": self.started,
                                                "served": self.served, "running": len(self.commands)})
            elif tag == b"s":
                server_link.send_message(conn, {"stopping": True})
                self._stop_listening()
        except OSError:
            pass
        conn.close()

    def _start_command(self, conn: socket.socket, request: dict, fds: list[int]) -> None:
        # the command keeps its connection (unused): should this server die, its client waits
        # for the command's end all the same, instead of leaving it running behind the prompt
        close = [*self.selector.get_map(), self.selector.fileno(), _LOCK[0]]
        spares = self._hand_spare()
        pid = os.fork()
        if pid == 0:  # pragma: no cover - the command's process
            from cnc_twin.server.runner import become_command

            become_command(request, fds, close, spares)
        for fd in fds:
            os.close(fd)
        if spares:
            self._let_spare_go()
        self.served += 1
        pidfd = os.pidfd_open(pid)
        self.commands[pid] = (conn, pidfd)
        self.selector.register(pidfd, selectors.EVENT_READ, ("ended", pid))
        conn.setblocking(True)
        try:
            server_link.send_message(conn, {"pid": pid})
        except OSError:  # the client is gone already: end the command as it would end
            os.kill(pid, signal.SIGTERM)
        self.selector.register(conn, selectors.EVENT_READ, ("client", pid))

    def _ended(self, pid: int) -> None:
        conn, pidfd = self.commands.pop(pid)
        self.selector.unregister(pidfd)
        os.close(pidfd)
        if conn.fileno() in self.selector.get_map():
            self.selector.unregister(conn)
        _, status = os.waitpid(pid, 0)
        try:
            server_link.send_message(conn, {"status": status})
        except OSError:
            pass
        conn.close()
        self.last_activity = time.monotonic()

    def _client_spoke(self, pid: int) -> None:
        conn, _ = self.commands[pid]
        try:
            data = conn.recv(64)
        except OSError:
            data = b""
        if not data:  # the client is gone (killed, its terminal closed): the command ends as on SIGTERM
            self.selector.unregister(conn)
            try:
                os.kill(pid, signal.SIGTERM)
            except ProcessLookupError:
                pass


_LOCK = [-1]
"""the descriptor holding this server's lock (the commands close it)"""


def _tidy(folder: Path) -> None:
    """Remove the lock files (and empty logs) of this installation's servers that no longer run
    (none holds the lock)."""
    for lock in folder.glob(f"{server_link.family()}-*.lock"):
        try:
            fd = server_link.take_lock(lock)
            if fd is None:  # held: that server runs
                continue
            try:
                lock.unlink(missing_ok=True)
                log = lock.with_suffix(".log")
                if log.exists() and log.stat().st_size == 0:
                    log.unlink()
            finally:
                os.close(fd)
        except OSError:
            continue


def _wait_for(pid: int, timeout: float) -> None:
    """Until process ``pid`` has ended (at most ``timeout`` [s])."""
    try:
        pidfd = os.pidfd_open(pid)
    except OSError:  # ended already
        return
    try:
        select.select([pidfd], [], [], timeout)
    finally:
        os.close(pidfd)


def main(argv: list[str] | None = None) -> int:
    """``python -m cnc_twin.server.daemon KEY [--after PID]``: the server of ``KEY``, until it
    ends; the exit code (0 also when it is not needed: another server, or other code)."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) not in (1, 3) or (len(args) == 3 and args[1] != "--after"):
        print("usage: python -m cnc_twin.server.daemon KEY [--after PID]", file=sys.stderr)
        return 2
    key = args[0]
    # Python 3.12+ warns at every fork of a process with native threads: here OpenBLAS's and
    # Arrow's pools, which take their own care of a fork (pthread_atfork); forking is the point.
    warnings.filterwarnings("ignore", message=r"This process .* is multi-threaded", category=DeprecationWarning)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)
    folder = server_link.socket_folder()
    if key != server_link.server_key():
        return 0  # the code or the environment changed meanwhile: not needed
    _LOCK[0] = server_link.take_lock(server_link.lock_path(key))
    if _LOCK[0] is None:
        return 0  # another is starting: not needed
    if len(args) == 3:
        # The command that started it is running: it gets the machine's CPUs; the server warms
        # up after it (not niced: its commands inherit its priority, which could not be raised again).
        _wait_for(int(args[2]), server_link.IDLE_SECONDS)
    warm_up()
    path = server_link.socket_path(key)
    staged = folder / f".{key}.{os.getpid()}.sock"
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    staged.unlink(missing_ok=True)
    listener.bind(str(staged))
    listener.listen(64)
    os.replace(staged, path)  # ready: clients find it from now on
    server_link.stop_servers(server_link.outdated(key, server_link.running_servers()))
    _tidy(folder)
    Server(key, listener, path).serve()
    with contextlib.suppress(OSError):  # a log with nothing in it says nothing
        if server_link.log_path(key).stat().st_size == 0:
            server_link.log_path(key).unlink()
    return 0


if __name__ == "__main__":
    code = main()
    os._exit(code)
