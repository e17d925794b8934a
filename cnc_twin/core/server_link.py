"""The ``cnc-twin`` command's side of the warm server: find it, hand it the command, relay signals.

A command needs numpy, MuJoCo, numba and the twin's compiled kernels in its process; loading them
takes a new interpreter a second or more, several times a short run's own clock. The warm server
(:mod:`cnc_twin.server.daemon`) is a process that has loaded them once. For ``run``, ``serve``, ``validate``,
``gcode``, ``list``, ``schema`` and ``sweep`` (whose local workers are then forks of it too) the command (the client, which imports nothing heavy) connects to it over a
Unix socket and sends its arguments, working directory, environment, umask, resource limits and
its stdin, stdout and stderr (the descriptors themselves). The server forks a process that
becomes the command (:mod:`cnc_twin.server.runner`) and reports its process id, then its exit.
The client forwards SIGINT, SIGTERM, SIGHUP and SIGQUIT to it and ends with its status, so the
shell, scripts and Ctrl-C see the command as if it ran in the client.

With no server running the command runs in the client's own process, as always, and starts one
in the background (detached; it warms up once that command has ended) for the next command. A
server serves one installation, code and environment (:func:`server_key`); it ends after
:data:`IDLE_SECONDS` without a command, and when a server for newer code of the same environment
starts (:func:`outdated`). ``CNC_TWIN_SERVER=off`` turns all of it off; ``cnc-twin server --stop``
ends the running servers.

The socket lives in ``$XDG_RUNTIME_DIR/cnc-twin`` (or ``/tmp/cnc-twin-<uid>``), a folder only
its owner may use; the server also checks each caller's user id.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import signal
import socket
import stat
import subprocess
import sys
from pathlib import Path

from cnc_twin.core.helpers import module_command
from cnc_twin.core.messages import framed, read_message

VARIABLE = "CNC_TWIN_SERVER"
"""``off`` (or ``0``, ``no``): every command in its own process, no server started"""

COMMANDS = ("run", "serve", "validate", "gcode", "list", "schema", "sweep")
"""the commands a warm server runs"""

IDLE_SECONDS = 900.0
"""a server with no command for this long ends [s]"""

FORWARDED = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP, signal.SIGQUIT)
"""signals the client passes on to the command's process"""

RLIMITS = tuple(getattr(__import__("resource"), name) for name in
                ("RLIMIT_AS", "RLIMIT_DATA", "RLIMIT_CPU", "RLIMIT_FSIZE", "RLIMIT_NOFILE", "RLIMIT_CORE"))
"""the caller's resource limits the command takes (lowered only: ``ulimit -v`` holds as without a server)"""

_ENVIRONMENT_KEYS = ("PYTHON", "NUMBA_", "OPENBLAS_", "OMP_", "MKL_", "MUJOCO", "LD_", "LANG", "LC_", "VIRTUAL_ENV")
"""variables read while modules load (or the interpreter starts): another value needs another server"""

PACKAGE = Path(__file__).resolve().parent.parent

MAX_FOLDER_CHARACTERS = 60
"""a socket folder longer than this is not used (the socket's name, staged, takes up to 47 more)"""


def enabled() -> bool:
    """Whether commands may use (and start) a warm server: not with ``CNC_TWIN_SERVER=off``."""
    return os.environ.get(VARIABLE, "").strip().lower() not in ("off", "0", "no", "false")


def socket_folder() -> Path:
    """The private folder of this user's server sockets (made if missing)."""
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    base = Path(runtime) / "cnc-twin" if runtime and Path(runtime).is_dir() else Path(f"/tmp/cnc-twin-{os.getuid()}")
    if len(str(base)) > MAX_FOLDER_CHARACTERS:  # a Unix socket's path has room for 107 bytes in all
        base = Path(f"/tmp/cnc-twin-{os.getuid()}")
    base.mkdir(mode=0o700, parents=True, exist_ok=True)
    info = base.lstat()
    if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid() or info.st_mode & 0o077:
        raise PermissionError(f"{base}: not a folder of this user's alone")
    return base


def family() -> str:
    """This installation's servers (one interpreter, one package folder): a short digest."""
    interpreter = os.path.realpath(sys.executable)  # python, python3, python3.11: one interpreter
    return hashlib.sha256(f"{interpreter}\0{sys.prefix}\0{PACKAGE}".encode()).hexdigest()[:10]


def server_key() -> str:
    """What a server must share with the command to run it as the command's own process would,
    as ``FAMILY-CODE-ENVIRONMENT`` (short digests): the installation (:func:`family`); the
    interpreter, the package's modules (each file's size and time) and the installed libraries
    (each site-packages folder's time changes when one is added or removed); the environment
    variables read as modules load (``PYTHONPATH`` among them)."""
    code = hashlib.sha256()
    code.update(f"{sys.version}\0{os.getuid()}\0".encode())
    # the installed libraries' folders (not a script's folder, the directory of ``python -m`` or
    # what a test runner prepends: modules there are not what the server loads)
    for folder in sorted({path for path in sys.path if path.endswith(("site-packages", "dist-packages"))}):
        try:
            code.update(f"{folder}\0{os.stat(folder or '.').st_mtime_ns}\0".encode())
        except OSError:
            code.update(f"{folder}\0-\0".encode())
    for root, folders, files in os.walk(PACKAGE):
        folders[:] = sorted(name for name in folders if name != "__pycache__")
        for name in sorted(files):
            if name.endswith((".py", ".xml", ".yaml", ".mjb")):
                info = os.stat(os.path.join(root, name))
                code.update(f"{root}/{name}\0{info.st_size}\0{info.st_mtime_ns}\0".encode())
    environment = hashlib.sha256()
    for name in sorted(os.environ):
        if name.startswith(_ENVIRONMENT_KEYS):
            environment.update(f"{name}={os.environ[name]}\0".encode())
    return f"{family()}-{code.hexdigest()[:12]}-{environment.hexdigest()[:8]}"


def outdated(key: str, others: list[Path]) -> list[Path]:
    """The sockets among ``others`` of servers that the server of ``key`` replaces: this
    installation's, for the same environment, of other code (an edit, an upgrade). Servers for
    other environments stay: commands in both may alternate."""
    installation, _, environment = key.split("-")
    out = []
    for path in others:
        parts = path.name.removesuffix(".sock").split("-")
        if len(parts) == 3 and parts[0] == installation and parts[2] == environment and path.name != f"{key}.sock":
            out.append(path)
    return out


def socket_path(key: str) -> Path:
    """The socket the server of ``key`` listens on."""
    return socket_folder() / f"{key}.sock"


def send_message(sock: socket.socket, message) -> None:
    """Send ``message`` on ``sock``, framed (pickled after its length)."""
    sock.sendall(framed(message))


def receive_message(sock: socket.socket):
    """The next framed message on ``sock``; None if it closed first."""
    return read_message(sock.recv)


def lock_path(key: str) -> Path:
    """The file whose lock the server of ``key`` holds while it runs."""
    return socket_folder() / f"{key}.lock"


def take_lock(path: Path) -> int | None:
    """A descriptor holding the lock of ``path`` (made if missing), or None: another process holds it."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


def connect(key: str) -> socket.socket | None:
    """A connection to the running server for ``key``; None if there is none."""
    try:
        path = socket_path(key)
    except OSError:
        return None
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        sock.connect(str(path))
    except OSError:
        sock.close()
        return None
    return sock


def start_server(key: str, *, after: int | None = None) -> subprocess.Popen:
    """Start a server for ``key`` in the background: detached (its own session, no terminal, none
    of this process's descriptors); it warms up once process ``after`` has ended (the command
    that starts it keeps the CPUs), and exits at once if one is starting already."""
    wait = [] if after is None else ["--after", str(after)]
    with open(log_path(key), "ab") as log:  # what it says, should it fail, is kept here
        return subprocess.Popen(module_command("cnc_twin.server.daemon", [key, *wait]), stdin=subprocess.DEVNULL,
                                stdout=log, stderr=log, close_fds=True, start_new_session=True)


def log_path(key: str) -> Path:
    """Where the server of ``key`` writes what goes wrong in it."""
    return socket_folder() / f"{key}.log"


def delegate(argv: list[str]) -> int | None:
    """Run the command ``argv`` (the words after ``cnc-twin``) in a warm server's process and
    return its exit status; None when it was not handed over (no server, or not a command it
    runs): the caller runs it itself. Starts a server for next time when none is running."""
    if not argv or argv[0] not in COMMANDS or not enabled():
        return None
    try:
        key = server_key()
        sock = connect(key)
    except OSError:  # no private folder for the socket, a package file vanishing mid-walk...
        return None
    if sock is None:
        try:
            start_server(key, after=os.getpid())
        except OSError:
            pass
        return None
    with sock:
        return _hand_over(sock, argv)


def _hand_over(sock: socket.socket, argv: list[str]) -> int | None:
    import resource

    pending: list[int] = []
    runner = [0]

    def forward(signum: int, _frame) -> None:
        if runner[0]:
            try:
                os.kill(runner[0], signum)
            except ProcessLookupError:  # it has just ended: its status is on the way
                pass
        else:
            pending.append(signum)

    previous = {signum: signal.signal(signum, forward) for signum in FORWARDED}
    umask = os.umask(0o022)
    os.umask(umask)
    request = {"argv": argv, "cwd": os.getcwd(), "env": dict(os.environ), "umask": umask,
               "rlimits": {limit: resource.getrlimit(limit) for limit in RLIMITS}}
    try:
        socket.send_fds(sock, [b"c"], [0, 1, 2])  # the command's stdin, stdout, stderr, then what to run
        send_message(sock, request)
        started = receive_message(sock)
    except OSError:
        started = None
    if not isinstance(started, dict) or "pid" not in started:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        for signum in pending:  # nothing started: the signal is this process's own again
            os.kill(os.getpid(), signum)
        return None  # the server went away before starting it: run it here
    runner[0] = started["pid"]
    for signum in pending:
        forward(signum, None)
    ended = receive_message(sock)
    if not isinstance(ended, dict) or "status" not in ended:
        os.write(2, b"cnc-twin: the warm server ended while the command ran (no exit status)\n")
        return 1
    code = os.waitstatus_to_exitcode(ended["status"])
    if code < 0:  # killed by a signal: end the same way, so the caller sees what it would have
        signal.signal(-code, signal.SIG_DFL)
        os.kill(os.getpid(), -code)
        return 128 - code
    return code


def _ask(path: Path, tag: bytes):
    """The server at ``path``'s answer to the one-byte request ``tag``; OSError if nobody answers."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.settimeout(5.0)
        sock.connect(str(path))
        sock.sendall(tag)
        return receive_message(sock)


def server_status(path: Path) -> dict | None:
    """What the server at ``path`` says of itself (its process id, key, start time, commands
    served and running); None if nobody answers there."""
    try:
        answer = _ask(path, b"?")
    except OSError:
        return None
    return answer if isinstance(answer, dict) else None


def running_servers() -> list[Path]:
    """The sockets of this user's servers of this installation (any key)."""
    try:
        return sorted(socket_folder().glob(f"{family()}-*.sock"))
    except OSError:
        return []


def stop_servers(paths: list[Path] | None = None) -> int:
    """Ask the servers at ``paths`` (default: all of :func:`running_servers`) to end; commands
    they are running go on to their end. Returns how many answered."""
    stopped = 0
    for path in running_servers() if paths is None else paths:
        try:
            if _ask(path, b"s") == {"stopping": True}:
                stopped += 1
        except OSError:
            path.unlink(missing_ok=True)  # nobody listens there: a server that died without tidying
    return stopped
