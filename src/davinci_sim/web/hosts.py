"""Addresses the web servers bind to and the ones they show."""

from __future__ import annotations

#: Hosts that bind every interface.
EVERY_INTERFACE = ("0.0.0.0", "", "::")


def binds_everywhere(host: str) -> bool:
    """Whether binding ``host`` listens on every interface."""
    return host in EVERY_INTERFACE


def shown_host(host: str) -> str:
    """The host to put in an address a person opens on this machine: loopback for a server
    bound to every interface, else the host itself."""
    return "127.0.0.1" if binds_everywhere(host) else host
