"""Password hashes of OPC UA users: the format, the cost a verifier will compute, hashing.

A hash is a string (``motion-server hash-password`` prints one)::

    scrypt$<n>$<r>$<p>$<salt, base64>$<key, base64>

scrypt from :mod:`hashlib` with a random 16-byte salt and a 32-byte key; the default cost
is n = 2**14, r = 8, p = 1 (16 MiB and about 0.1 s per login on a small machine).

A site map may name any cost a login can afford: scrypt needs 128·n·r bytes of memory
and time in proportion to n·r·p. A cost above :data:`MAX_SCRYPT_MEMORY` (four times the
default memory) or :data:`MAX_SCRYPT_WORK` (eight times the default work) is refused when
the map is loaded, so no login ever attempts a computation OpenSSL refuses
("memory limit exceeded") or that keeps the front-end busy for seconds.

This module imports no protocol library: the site-map schema checks hashes with it.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import secrets

SCRYPT_N = 2**14
SCRYPT_R = 8
SCRYPT_P = 1
SALT_BYTES = 16
KEY_BYTES = 32
#: scrypt's working memory is 128·n·r bytes: at most 64 MiB (the default needs 16 MiB)
MAX_SCRYPT_MEMORY = 64 * 2**20
#: n·r·p, in proportion to the time a login takes: at most 8 times the default's
MAX_SCRYPT_WORK = 8 * SCRYPT_N * SCRYPT_R * SCRYPT_P
MAX_SCRYPT_R = 32
MAX_SCRYPT_P = 16
MIN_SALT_BYTES = 8
MIN_KEY_BYTES = 16


def cost_problem(n: int, r: int, p: int) -> str | None:
    """Why an scrypt cost cannot be used (None: it can). The conditions are those of
    RFC 7914 and of OpenSSL's implementation, which :func:`hashlib.scrypt` calls."""
    if n < 2 or n & (n - 1):
        return f"scrypt n={n} is not a power of two"
    if not 1 <= r <= MAX_SCRYPT_R or not 1 <= p <= MAX_SCRYPT_P:
        return f"scrypt r={r} p={p}: r must be 1..{MAX_SCRYPT_R} and p 1..{MAX_SCRYPT_P}"
    if n >= 2 ** (16 * r):
        return f"scrypt n={n} must be below 2**(16·r) = {2 ** (16 * r)} (RFC 7914)"
    # OpenSSL allocates 128·r·p bytes for B and 128·r·(n + 2) for V, within ``maxmem``
    need = 128 * r * (n + p + 2)
    if need > min(MAX_SCRYPT_MEMORY, maxmem(n, r)):
        return (
            f"scrypt cost n={n} r={r} p={p} needs {need / 2**20:.1f} MiB; "
            f"a login may use at most {min(MAX_SCRYPT_MEMORY, maxmem(n, r)) / 2**20:.1f} MiB"
        )
    if n * r * p > MAX_SCRYPT_WORK:
        return f"scrypt cost n·r·p = {n * r * p} is above {MAX_SCRYPT_WORK} (too slow per login)"
    return None


def maxmem(n: int, r: int) -> int:
    """The memory bound a verifier passes to :func:`hashlib.scrypt` for a cost."""
    return 256 * n * r + 2**20


def parse_hash(text: str) -> tuple[int, int, int, bytes, bytes]:
    """(n, r, p, salt, key) of a hash string; ValueError naming what is wrong."""
    parts = text.split("$")
    if len(parts) != 6 or parts[0] != "scrypt":
        raise ValueError("expected scrypt$<n>$<r>$<p>$<salt>$<key> (motion-server hash-password)")
    try:
        n, r, p = (int(x) for x in parts[1:4])
        salt = base64.b64decode(parts[4], validate=True)
        key = base64.b64decode(parts[5], validate=True)
    except ValueError:
        raise ValueError("the cost fields must be integers and salt/key base64") from None
    problem = cost_problem(n, r, p)
    if problem:
        raise ValueError(problem)
    if len(salt) < MIN_SALT_BYTES or len(key) < MIN_KEY_BYTES:
        raise ValueError("salt or key too short")
    return n, r, p, salt, key


def hash_password(password: str, n: int = SCRYPT_N, r: int = SCRYPT_R, p: int = SCRYPT_P) -> str:
    """A salted scrypt hash of ``password`` in the documented string format."""
    problem = cost_problem(n, r, p)
    if problem:
        raise ValueError(problem)
    salt = secrets.token_bytes(SALT_BYTES)
    key = scrypt(password, salt, n, r, p)
    return "$".join(["scrypt", str(n), str(r), str(p), _b64(salt), _b64(key)])


def verify_password(password: str, hashed: str) -> bool:
    """True when ``password`` matches ``hashed`` (False for a malformed hash)."""
    try:
        n, r, p, salt, key = parse_hash(hashed)
    except ValueError:
        return False
    return hmac.compare_digest(scrypt(password, salt, n, r, p, len(key)), key)


def scrypt(password: str, salt: bytes, n: int, r: int, p: int, size: int = KEY_BYTES) -> bytes:
    return hashlib.scrypt(
        password.encode("utf-8"), salt=salt, n=n, r=r, p=p, maxmem=maxmem(n, r), dklen=size
    )


def _b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")
