"""three.js for the page's endoscope view: fetched once from the npm registry, checked, kept.

The page draws the endoscope itself with `three.js <https://threejs.org>`_ (MIT), the
WebGL library made for the job (:mod:`davinci_sim.web.endoscope_stream` says what it draws).
The project ships no copy of it: ``make install`` runs ``python -m davinci_sim.web.vendor``,
which downloads the pinned release's tarball from the npm registry, checks it against the
registry's published SHA-512 (:data:`THREE_INTEGRITY`, pinned here: a changed tarball is
refused), and keeps the two ES modules the page imports (``three.module.js``, which imports
``three.core.js``) with the licence, in ``<sys.prefix>/share/davinci-sim/three-<version>``
(the virtual environment's) or, where that is not writable, in the user's cache
(``$XDG_CACHE_HOME/davinci-sim``). The web console serves them at ``/vendor/<name>``; where
they are missing, the page shows the server's images and says so.
"""

from __future__ import annotations

import base64
import hashlib
import io
import os
import shutil
import sys
import tarfile
import tempfile
import urllib.request
from pathlib import Path

THREE_VERSION = "0.187.0"
#: The npm registry's ``dist.integrity`` of ``three@0.187.0`` (Subresource Integrity form).
THREE_INTEGRITY = (
    "sha512-"
    "Qiu7R+Cmh8CstZsY1uJOSWnVlfo7ZtNLV7mF8Jltk3LB3AtDu9cRZlcnRKkAk8Y4z6KKw35z7Y7Urd7jWY8etA=="
)
THREE_TARBALL = f"https://registry.npmjs.org/three/-/three-{THREE_VERSION}.tgz"
#: The files the page needs, as named in the tarball (``package/`` prefix) and served.
THREE_FILES = {
    "three.module.js": "package/build/three.module.js",
    "three.core.js": "package/build/three.core.js",
    "LICENSE": "package/LICENSE",
}


def candidate_dirs() -> list[Path]:
    """Where the files may be, in the order they are looked for (and written)."""
    name = f"three-{THREE_VERSION}"
    dirs = [Path(sys.prefix) / "share" / "davinci-sim" / name]
    cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    dirs.append(Path(cache) / "davinci-sim" / name)
    return dirs


def three_dir() -> Path | None:
    """The directory holding every file of :data:`THREE_FILES`, or None (not fetched)."""
    for d in candidate_dirs():
        if all((d / n).is_file() for n in THREE_FILES):
            return d
    return None


def vendor_file(name: str) -> bytes | None:
    """The bytes of the served file ``name`` (a key of :data:`THREE_FILES`), or None."""
    d = three_dir()
    if d is None or name not in THREE_FILES:
        return None
    return (d / name).read_bytes()


def check_integrity(data: bytes, integrity: str = THREE_INTEGRITY) -> None:
    """Raise ``ValueError`` unless ``data``'s SHA-512 is the Subresource Integrity value."""
    algorithm, _, expected = integrity.partition("-")
    if algorithm != "sha512":
        raise ValueError(f"unsupported integrity algorithm {algorithm!r}")
    got = base64.b64encode(hashlib.sha512(data).digest()).decode()
    if got != expected:
        raise ValueError(f"three.js tarball: SHA-512 {got} is not the pinned {expected}")


def unpack(data: bytes, target: Path, integrity: str = THREE_INTEGRITY) -> Path:
    """Write :data:`THREE_FILES` of the tarball ``data``, checked against ``integrity``,
    into ``target``, atomically (a half-written directory is never found).

    Raises:
        ValueError: the tarball does not match ``integrity``, or lacks one of the files
            (nothing is written).
    """
    check_integrity(data, integrity)
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=".three-", dir=target.parent))
    staging.chmod(0o755)  # (mkdtemp's is the owner's only; the files are public)
    try:
        with tarfile.open(fileobj=io.BytesIO(data), mode="r:gz") as tar:
            for name, member in THREE_FILES.items():
                try:
                    extracted = tar.extractfile(member)
                except KeyError:
                    extracted = None
                if extracted is None:
                    raise ValueError(f"three.js tarball: {member} is not a file")
                (staging / name).write_bytes(extracted.read())
        if target.exists():
            shutil.rmtree(target)
        staging.rename(target)
    finally:
        if staging.exists():
            shutil.rmtree(staging)
    return target


def fetch_three(timeout: float = 120.0) -> Path:
    """Download, check and keep three.js unless already kept; returns its directory.

    Raises:
        OSError: the registry cannot be reached, or no candidate directory is writable.
        ValueError: the tarball does not match :data:`THREE_INTEGRITY`.
    """
    found = three_dir()
    if found is not None:
        return found
    with urllib.request.urlopen(THREE_TARBALL, timeout=timeout) as response:  # noqa: S310
        data = response.read()
    errors = []
    for d in candidate_dirs():
        try:
            return unpack(data, d)
        except PermissionError as e:
            errors.append(f"{d}: {e}")
    raise OSError("no writable directory for three.js: " + "; ".join(errors))


def main() -> int:
    try:
        path = fetch_three()
    except (OSError, ValueError) as e:
        print(f"three.js {THREE_VERSION} not fetched: {e}", file=sys.stderr)
        print("the web console will show the server's images instead", file=sys.stderr)
        return 1
    print(f"three.js {THREE_VERSION}: {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
