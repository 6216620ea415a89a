"""Token check of the rosbridge ``auth`` op (rosbridge.md §1.6, RB1 rosauth).

Two forms are accepted: the token itself as ``mac`` (simple shared-secret clients), or the
rosauth MAC: the hex SHA-512 of ``secret + client + dest + rand + t + level + end``, which
keeps the secret off the wire; that form is refused once ``end`` (seconds since the epoch)
has passed.
"""

from __future__ import annotations

import hashlib
import hmac
import time

from davinci_sim.bridge.rosbridge.protocol import Auth


def rosauth_mac(secret: str, op: Auth) -> str:
    """The rosauth MAC of an ``auth`` op's fields."""
    text = f"{secret}{op.client}{op.dest}{op.rand}{op.t}{op.level}{op.end}"
    return hashlib.sha512(text.encode("utf-8")).hexdigest()


def check_auth(secret: str, op: Auth, now: float | None = None) -> tuple[bool, str]:
    """``(True, "")`` if ``op`` proves knowledge of ``secret``, else ``(False, reason)``."""
    if hmac.compare_digest(op.mac.encode("utf-8"), secret.encode("utf-8")):
        return True, ""
    if hmac.compare_digest(op.mac.encode("utf-8"), rosauth_mac(secret, op).encode("utf-8")):
        try:
            end = float(op.end)
        except (TypeError, ValueError):
            return False, f"auth: 'end' must be a time, got {op.end!r}"
        if end and end < (time.time() if now is None else now):
            return False, "auth: the authorization has expired"
        return True, ""
    return False, "auth: invalid token ('mac' is neither the server's token nor its rosauth MAC)"
