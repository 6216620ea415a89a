"""three.js's fetch: the pinned checksum is enforced and a kept copy is whole or absent."""

from __future__ import annotations

import base64
import hashlib
import io
import tarfile

import pytest

from davinci_sim.web import vendor


def tarball(files: dict[str, bytes]) -> bytes:
    out = io.BytesIO()
    with tarfile.open(fileobj=out, mode="w:gz") as tar:
        for name, body in files.items():
            info = tarfile.TarInfo(name)
            info.size = len(body)
            tar.addfile(info, io.BytesIO(body))
    return out.getvalue()


def integrity_of(data: bytes) -> str:
    return "sha512-" + base64.b64encode(hashlib.sha512(data).digest()).decode()


PACKAGE = {member: f"// {name}\n".encode() for name, member in vendor.THREE_FILES.items()}


def test_a_tarball_that_is_not_the_pinned_one_is_refused():
    data = tarball(PACKAGE)
    vendor.check_integrity(data, integrity_of(data))
    changed = data[:-1] + bytes([data[-1] ^ 1])
    with pytest.raises(ValueError, match="SHA-512"):
        vendor.check_integrity(changed, integrity_of(data))
    with pytest.raises(ValueError, match="SHA-512"):
        vendor.check_integrity(data)  # not three.js 0.187.0's
    with pytest.raises(ValueError, match="algorithm"):
        vendor.check_integrity(data, "sha1-" + integrity_of(data)[7:])


def test_the_files_are_kept_whole_or_not_at_all(tmp_path):
    data = tarball(PACKAGE)
    target = tmp_path / "share" / "three"
    assert vendor.unpack(data, target, integrity_of(data)) == target
    assert sorted(p.name for p in target.iterdir()) == sorted(vendor.THREE_FILES)
    assert (target / "three.core.js").read_bytes() == b"// three.core.js\n"
    partial = tarball({k: v for k, v in PACKAGE.items() if not k.endswith("three.core.js")})
    other = tmp_path / "other"
    with pytest.raises(ValueError, match=r"three\.core\.js"):
        vendor.unpack(partial, other, integrity_of(partial))
    assert not other.exists() and list(tmp_path.iterdir()) == [tmp_path / "share"]


def test_only_the_listed_files_are_served(monkeypatch, tmp_path):
    monkeypatch.setattr(vendor, "candidate_dirs", lambda: [tmp_path / "none", tmp_path / "t"])
    assert vendor.three_dir() is None and vendor.vendor_file("three.module.js") is None
    data = tarball(PACKAGE)
    vendor.unpack(data, tmp_path / "t", integrity_of(data))
    assert vendor.three_dir() == tmp_path / "t"
    assert vendor.vendor_file("three.module.js") == b"// three.module.js\n"
    for name in ("../vendor.py", "three.cjs", ""):
        assert vendor.vendor_file(name) is None
