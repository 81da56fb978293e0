"""A fork server: supervised simulation children forked from a single-threaded helper process.

A process that runs several threads (a Dask worker) cannot fork its supervised children safely
(a fork copies one thread, and any lock another one held), and a new interpreter for each costs
about half a second of imports. The fork server is a helper process started once (lazily, by
exec: ``python -c "...fork_server.main..." <fd>``) per supervising process, with
:mod:`heliostep.cosim.child` (numpy, the master, the kernel module) imported; it runs one thread
and forks one simulation child per request, in a few milliseconds.

Protocol. The supervisor holds one end of a socket pair, the *control* socket; the server the
other (its ``<fd>``). Per request (:func:`spawn`, any thread; a lock keeps each message whole):

1. the supervisor makes a per-request socket pair, the *status* connection, and sends on it the
   pickled ``(record, tmpdir)`` (the child's call record, its temporary folder);
2. it sends on the control socket one byte with four file descriptors (``SCM_RIGHTS``): the
   child's end of the run's socket (``theirs``), the server's end of the status connection and
   the supervisor's stdout and stderr (the child writes where an executed one would);
3. the server forks; the child closes the server's sockets, takes the stdout and stderr, and
   runs :func:`heliostep.cosim.child.serve` (which reads the pickled request from ``theirs``),
   then ``os._exit(status)``; the server answers ``("pid", pid)`` on the status connection;
4. the supervisor may send ``("kill",)`` there (the server kills the child if it still runs: no
   pid is ever signalled after it was reaped); the server reaps the child (``SIGCHLD``) and sends
   ``("exit", code)`` (negative: the signal that killed it, as :class:`subprocess.Popen` says),
   then closes the connection. :class:`Served` is the supervisor's handle (``poll``, ``wait``,
   ``kill``, ``pid``).

Lifetimes. The server ends when the control socket closes: the supervisor closed it (at exit,
``atexit``) or its process died, even by SIGKILL (the kernel closes its sockets); it kills its
children first. (Not ``PR_SET_PDEATHSIG``: it follows the *thread* that started the server, and
a Dask worker's thread may end while other threads' runs go on.) Each child dies with the server
(``PR_SET_PDEATHSIG``, :func:`~heliostep.cosim.child.die_with_supervisor`: the server is its
parent and runs one thread), so nothing outlives the supervising process. A server that died is
started again once; if that fails :func:`spawn` returns None and the supervisor executes its
child instead (and does from then on). A server is started for one environment and working
folder (those of a new interpreter): when they change, the next idle moment starts a new one.
"""

from __future__ import annotations

import atexit
import os
import select
import signal
import socket
import subprocess
import sys
import threading
import time as clock
import traceback
from multiprocessing.connection import Connection

__all__ = ["AVAILABLE", "READY_LIMIT", "Served", "close", "main", "spawn"]

#: Whether this platform can run the server (AF_UNIX sockets that pass file descriptors, fork).
AVAILABLE = hasattr(os, "fork") and hasattr(socket, "AF_UNIX") and hasattr(socket, "send_fds")

#: Seconds the server may take to answer a request with its child's pid (its own start included:
#: an interpreter and its imports) before it counts as broken.
READY_LIMIT = 60.0

#: The server's command (not ``-m``: this module is imported with its package before it would run).
_MAIN = "import sys; from heliostep.cosim.fork_server import main; sys.exit(main(sys.argv))"

_WAKE = 1.0  # [s] the server's longest wait: it also looks whether its parent is still there


class Served:
    """A child of the fork server, seen as :class:`subprocess.Popen` sees one (``poll``, ``wait``, ``kill``)."""

    def __init__(self, pid: int, status: Connection):
        self.pid, self.status = pid, status
        self.returncode: int | None = None

    def _take(self, timeout: float | None) -> None:
        """The exit code, if the server sends it within ``timeout`` [s] (None: until it does)."""
        if self.returncode is not None or timeout is not None and not self.status.poll(timeout):
            return
        try:
            kind, code = self.status.recv()
        except (EOFError, OSError):  # the server died: its child with it (PR_SET_PDEATHSIG)
            kind, code = "exit", -int(signal.SIGKILL)
        if kind == "exit":
            self.returncode = int(code)
            self.status.close()

    def poll(self) -> int | None:
        self._take(0)
        return self.returncode

    def wait(self) -> int:
        while self.returncode is None:
            self._take(None)
        return self.returncode

    def kill(self) -> None:
        if self.returncode is None:
            try:
                self.status.send(("kill",))
            except OSError:  # the server is gone, and its child with it
                pass


class _Client:
    """The supervising process's side: the server's process and the control socket, started lazily."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.process: subprocess.Popen | None = None
        self.control: socket.socket | None = None
        self.key: tuple | None = None  # the environment and folder the server was started in
        self.broken = False  # a fresh server failed: the children are executed from now on
        self.running = 0  # requests whose child has not ended yet

    def spawn(self, theirs: socket.socket, record: str, tmpdir: str) -> Served | None:
        key = (tuple(sorted(os.environ.items())), os.getcwd())
        with self.lock:
            if self.broken:
                return None
            if self.key != key and self.running:  # another thread's runs use the old server
                return None
            for fresh in (self.key != key or not self._alive(), True):
                if fresh:
                    self._stop()
                    self._start(key)
                served = self._request(theirs, record, tmpdir)
                if served is not None:
                    self.running += 1
                    return _Counted(served, self)
            self.broken = True
            self._stop()
            return None

    def _alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def _start(self, key: tuple) -> None:
        ours, server_end = socket.socketpair()
        command = [sys.executable, "-c", _MAIN, str(server_end.fileno())]
        try:
            self.process = subprocess.Popen(command, pass_fds=[server_end.fileno()], stdin=subprocess.DEVNULL)
        except OSError:
            ours.close()
            self.process = None
        else:
            self.control, self.key = ours, key
        finally:
            server_end.close()

    def _request(self, theirs: socket.socket, record: str, tmpdir: str) -> Served | None:
        if self.control is None or self.process is None:
            return None
        mine, server_end = socket.socketpair()
        status = Connection(mine.detach())
        try:
            status.send((record, tmpdir))
            outputs = [fd for fd in (1, 2) if _open(fd)]
            socket.send_fds(self.control, [bytes([len(outputs)])], [theirs.fileno(), server_end.fileno(), *outputs])
            deadline = clock.monotonic() + READY_LIMIT
            while not status.poll(0.05):
                if self.process.poll() is not None or clock.monotonic() > deadline:
                    raise EOFError("the fork server did not answer")
            kind, pid = status.recv()
            if kind == "pid":
                return Served(int(pid), status)
        except (OSError, EOFError, ValueError):
            pass
        finally:
            server_end.close()
        status.close()
        return None

    def _stop(self) -> None:
        """The server ended (its control socket closed: it kills its children and exits) and reaped."""
        if self.control is not None:
            self.control.close()
            self.control = None
        if self.process is not None:
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
            self.process = None
        self.key = None

    def forget(self) -> None:
        """In a forked copy of the supervising process: the server is the parent's, not this one's."""
        self.lock = threading.Lock()
        if self.control is not None:
            self.control.close()
        self.control = self.process = self.key = None
        self.running = 0


class _Counted(Served):
    """A :class:`Served` that tells the client when its child has ended."""

    def __init__(self, served: Served, client: _Client):
        super().__init__(served.pid, served.status)
        self.client = client

    def _take(self, timeout: float | None) -> None:
        ended = self.returncode is not None
        super()._take(timeout)
        if not ended and self.returncode is not None:
            with self.client.lock:
                self.client.running -= 1


def _open(fd: int) -> bool:
    try:
        os.fstat(fd)
    except OSError:
        return False
    return True


_CLIENT = _Client()
if AVAILABLE:
    os.register_at_fork(after_in_child=_CLIENT.forget)


def spawn(theirs: socket.socket, record: str, tmpdir: str) -> Served | None:
    """A simulation child forked by this process's fork server (started if needed), serving the
    run's socket end ``theirs`` (still to be closed here) with the call record ``record`` and the
    temporary folder ``tmpdir``; None when no server can (the caller executes the child instead)."""
    return _CLIENT.spawn(theirs, record, tmpdir) if AVAILABLE else None


@atexit.register
def close() -> None:
    """End this process's fork server (its children killed), if it runs."""
    with _CLIENT.lock:
        _CLIENT._stop()


def main(argv: list[str]) -> int:
    """The server: fork a child for each request on the control socket ``argv[1]`` (a file
    descriptor) until it closes or the parent is gone (see the module docstring)."""
    import heliostep.cosim.child  # noqa: F401 - imported once here, for every child

    for number in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):  # a terminal's signals: the children's too
        signal.signal(number, signal.SIG_IGN)
    parent, control = os.getppid(), socket.socket(fileno=int(argv[1]))
    wake_read, wake_write = os.pipe()
    os.set_blocking(wake_write, False)
    signal.set_wakeup_fd(wake_write)
    signal.signal(signal.SIGCHLD, lambda *_: None)
    children: dict[int, Connection] = {}  # pid: its status connection
    try:
        while os.getppid() == parent:
            watched = {connection.fileno(): pid for pid, connection in children.items()}
            ready, _, _ = select.select([control.fileno(), wake_read, *watched], [], [], _WAKE)
            if wake_read in ready:
                os.read(wake_read, 512)
            _reap(children)
            for fd in ready:
                if fd in watched and watched[fd] in children:
                    _answer(watched[fd], children)
            if control.fileno() in ready:
                message, fds, _, _ = socket.recv_fds(control, 1, 8)
                if not message:  # the supervisor closed it, or is gone
                    break
                _fork(fds, message[0], children, control, (wake_read, wake_write))
    finally:
        for pid in children:
            os.kill(pid, signal.SIGKILL)
        while children:
            try:
                _reap(children, block=True)
            except ChildProcessError:
                break
    return 0


def _reap(children: dict[int, Connection], block: bool = False) -> None:
    """Every child that ended reaped, its exit code sent on its status connection."""
    while children:
        pid, status = os.waitpid(-1, 0 if block else os.WNOHANG)
        if not pid:
            return
        connection = children.pop(pid, None)
        if connection is not None:
            try:
                connection.send(("exit", os.waitstatus_to_exitcode(status)))
            except OSError:  # the supervisor gave up waiting
                pass
            connection.close()
        if block:
            return


def _answer(pid: int, children: dict[int, Connection]) -> None:
    """A message from the supervisor on ``pid``'s status connection: kill it (or it hung up: the same)."""
    try:
        children[pid].recv()
    except (EOFError, OSError):
        pass
    os.kill(pid, signal.SIGKILL)  # not reaped yet (_reap runs first): the pid is still the child's


def _fork(fds: list[int], outputs: int, children: dict[int, Connection], control, wake: tuple[int, int]) -> None:
    """The child of one request: ``fds`` the run's socket end, the status connection, stdout and stderr."""
    theirs, status = fds[0], Connection(fds[1])
    try:
        record, tmpdir = status.recv()
    except (EOFError, OSError):
        record = None
    if record is None or len(fds) != 2 + outputs:
        for fd in fds:
            os.close(fd) if fd != fds[1] else status.close()
        return
    pid = os.fork()
    if pid == 0:
        server_fds = [control.fileno(), *wake, status.fileno(), *(c.fileno() for c in children.values())]
        _child(theirs, record, tmpdir, fds[2:], server_fds)
    for fd in (theirs, *fds[2:]):
        os.close(fd)
    children[pid] = status
    try:
        status.send(("pid", pid))
    except OSError:
        pass


def _child(theirs: int, record: str, tmpdir: str, outputs: list[int], server_fds: list[int]) -> None:
    """The forked child: the server's sockets closed, the supervisor's stdout and stderr taken, one run served."""
    status = 1
    try:
        signal.set_wakeup_fd(-1)
        signal.signal(signal.SIGCHLD, signal.SIG_DFL)
        for fd in server_fds:
            os.close(fd)
        for target, fd in zip((1, 2), outputs, strict=False):
            os.dup2(fd, target)
            os.close(fd)
        from heliostep.cosim.child import run

        status = run(Connection(theirs), record, tmpdir)
    except BaseException:  # noqa: BLE001 - as an interpreter would: the traceback, exit status 1
        traceback.print_exc()
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
