"""Files the tests make: maps drawn as ASCII grids, a CA and a server certificate for TLS, and a small tmpfs for
the full-disk tests, and an MCAP file of a crafted scenario."""

from __future__ import annotations

import contextlib
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from mcap.writer import Writer
from PIL import Image

# A small two-room map (white free, black walls), drawn like the tests' ASCII grids.
TWO_ROOMS = """
########################
#..........#...........#
#..........#...........#
#......................#
#..........#...........#
#..........#...........#
####.#######.......#####
#..........#...........#
#..........#...........#
#......................#
#..........#...........#
########################
"""


# A smaller map of five rooms, for the sweep tests' studies.
ROOMS = """
##############
#.....#......#
#............#
#.....#......#
###.#####.####
#............#
#.....#......#
##############
"""


def draw_map(ascii_map: str, path: Path) -> Path:
    """Save an ASCII grid (``#`` a wall, anything else free) as a greyscale PNG map: black walls, white floor."""
    rows = [ln.strip() for ln in ascii_map.strip().splitlines()]
    img = np.array([[0 if ch == "#" else 255 for ch in row] for row in rows], dtype=np.uint8)
    Image.fromarray(img, mode="L").save(path)
    return path


def crafted(path: Path, scenario: object) -> Path:
    """An MCAP file holding only a ``scenario`` metadata record (what the recorder writes first) of ``scenario``."""
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="adversary")
        w.add_metadata("scenario", {"run_id": "x", "scenario": json.dumps(scenario)})
        w.finish()
    return path


def make_certs(d: Path) -> tuple[Path, Path, Path]:
    """A CA, and a server certificate for localhost and 127.0.0.1 signed by it (rustls refuses a self-signed
    leaf): the paths of ``ca.pem``, ``cert.pem`` and ``key.pem`` in ``d``."""
    import datetime
    import ipaddress

    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    now = datetime.datetime.now(datetime.UTC)
    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "fleet test CA")])
    ca = (x509.CertificateBuilder().subject_name(ca_name).issuer_name(ca_name).public_key(ca_key.public_key())
          .serial_number(x509.random_serial_number()).not_valid_before(now - datetime.timedelta(hours=1))
          .not_valid_after(now + datetime.timedelta(days=1))
          .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
          .sign(ca_key, hashes.SHA256()))
    key = ec.generate_private_key(ec.SECP256R1())
    cert = (x509.CertificateBuilder().subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "localhost")]))
            .issuer_name(ca_name).public_key(key.public_key()).serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(hours=1)).not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(x509.SubjectAlternativeName([x509.DNSName("localhost"),
                                                        x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]),
                           critical=False)
            .add_extension(x509.BasicConstraints(ca=False, path_length=None), critical=True)
            .sign(ca_key, hashes.SHA256()))
    paths = d / "ca.pem", d / "cert.pem", d / "key.pem"
    paths[0].write_bytes(ca.public_bytes(serialization.Encoding.PEM))
    paths[1].write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    paths[2].write_bytes(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                           serialization.NoEncryption()))
    return paths


@contextlib.contextmanager
def tmpfs(mnt: Path, size: str):  # type: ignore[no-untyped-def]
    """A tmpfs of ``size`` (``mount -o size=``) mounted on ``mnt`` (made here), unmounted afterwards; a skip where
    mounting is not allowed."""
    mnt.mkdir()
    try:
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mnt)], capture_output=True,
                              text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired) as exc:
        pytest.skip(f"cannot mount a tmpfs here: {exc}")
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.strip() or done.returncode}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True, timeout=30)
