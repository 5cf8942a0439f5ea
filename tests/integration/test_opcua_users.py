"""Password hashes, the users secret file convention and the failed-login limiter."""

from __future__ import annotations

from pathlib import Path

import pytest

from motion_server import config
from motion_server.frontends.opcua_users import LoginLimiter, hash_password, verify_password
from tests.opcua_support import opcua_site


def test_hash_round_trip_and_salt() -> None:
    h1, h2 = hash_password("secret", n=2**10), hash_password("secret", n=2**10)
    assert h1 != h2  # salted
    assert h1.startswith("scrypt$1024$8$1$")
    assert verify_password("secret", h1) and verify_password("secret", h2)
    assert not verify_password("Secret", h1)
    assert not verify_password("secret", "scrypt$3$8$1$AAAA$BBBB")  # malformed: refused


def test_users_file_overrides_site_map_users_by_name(tmp_path: Path) -> None:
    site = opcua_site(tmp_path, {"operator": hash_password("a", n=2**10)})
    secret = tmp_path / "users.toml"
    override = hash_password("b", n=2**10)
    secret.write_text(
        f'[[users]]\nname = "operator"\nrole = "admin"\npassword_hash = "{override}"\n'
        f'[[users]]\nname = "extra"\nrole = "viewer"\npassword_hash = "{override}"\n'
    )
    users = {u.name: u for u in config.opcua_users(site, {config.USERS_FILE_ENV: str(secret)})}
    assert users["operator"].role == "admin" and users["operator"].password_hash == override
    assert set(users) == {"operator", "extra"}
    secret.write_text('[[users]]\nname = "x"\npassword_hash = "plain-text"\n')
    with pytest.raises(config.SiteMapError) as err:
        config.load_users_file(secret)
    assert "users.toml:3" in str(err.value) and "plain-text" not in str(err.value)


def test_limiter_locks_an_address_after_repeated_failures() -> None:
    now = [0.0]
    lim = LoginLimiter(max_failures=3, window=60.0, lockout=30.0, clock=lambda: now[0])
    for _ in range(3):
        assert not lim.locked("10.0.0.1")
        lim.failed("10.0.0.1")
    assert lim.locked("10.0.0.1") and not lim.locked("10.0.0.2")
    now[0] = 30.0
    assert not lim.locked("10.0.0.1")
