"""Who holds a TCP port: the words ``serve`` says when the port it was told to use is taken.

On Linux the kernel lists listening sockets in ``/proc/net/tcp`` and ``/proc/net/tcp6`` (the
local port in hex, the state ``0A`` = LISTEN, the socket's inode), and each process's open
sockets as ``/proc/<pid>/fd/*`` links to ``socket:[<inode>]``; the process's command line is
``/proc/<pid>/cmdline``. Processes of other users cannot be looked into without privileges:
then (and off Linux) the holder is unknown and the message leaves it out.
"""

from __future__ import annotations

import errno
import os
import socket
from dataclasses import dataclass
from pathlib import Path

#: The port a real rosbridge server listens on by default (and this one's default).
ROSBRIDGE_PORT = 9090
_LISTEN = "0A"


@dataclass(frozen=True)
class PortHolder:
    """A process listening on a port."""

    pid: int
    command: str
    """Its command line (arguments joined by spaces; cut to 120 characters)."""

    def __str__(self) -> str:
        return f"process {self.pid} ({self.command})"


def _listening_inodes(port: int, proc: Path) -> set[str]:
    inodes = set()
    for name in ("tcp", "tcp6"):
        try:
            lines = (proc / "net" / name).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if len(fields) < 10 or fields[3] != _LISTEN:
                continue
            if int(fields[1].rsplit(":", 1)[1], 16) == port:
                inodes.add(fields[9])
    return inodes


def port_holder(port: int, proc: str | Path = "/proc") -> PortHolder | None:
    """The process listening on TCP ``port`` (any address), or None if none is found or it
    cannot be known (another user's process, no ``/proc``)."""
    proc = Path(proc)
    inodes = _listening_inodes(port, proc)
    if not inodes:
        return None
    links = {f"socket:[{inode}]" for inode in inodes}
    try:
        pids = [p for p in os.listdir(proc) if p.isdigit()]
    except OSError:
        return None
    for pid in pids:
        fd_dir = proc / pid / "fd"
        try:
            fds = os.listdir(fd_dir)
        except OSError:
            continue  # gone, or another user's
        for fd in fds:
            try:
                if os.readlink(fd_dir / fd) in links:
                    return PortHolder(int(pid), _command(proc / pid))
            except OSError:
                continue
    return None


def _command(pid_dir: Path) -> str:
    try:
        raw = (pid_dir / "cmdline").read_bytes()
    except OSError:
        return "?"
    text = " ".join(a.decode("utf-8", "replace") for a in raw.split(b"\0") if a) or "?"
    return text if len(text) <= 120 else text[:117] + "..."


def port_taken(host: str, port: int) -> bool:
    """Whether ``port`` on ``host`` cannot be bound now (another socket listens on it). Binds
    and closes at once, with the address reuse the servers use, so a port left in TIME_WAIT
    by a server that just stopped counts as free (as it is to them)."""
    if port == 0:
        return False
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError as e:
            return e.errno == errno.EADDRINUSE
    return False


def taken_port_message(port: int, option: str, holder: PortHolder | None = None) -> str:
    """One line: the port is taken, by what if known, and which option chooses another."""
    text = f"port {port} is taken"
    if holder is not None:
        text += f" by {holder}"
    if port == ROSBRIDGE_PORT:
        text += " (9090 is also a real rosbridge server's default port: is one running?)"
    return f"{text}; choose another with {option} PORT"
