"""``motion-server check`` builds what ``run`` builds, and says what is wrong in one line.

Each case here gave a Python traceback, or was accepted and then failed (or misbehaved)
when the server ran. Now every one is a single line naming the file, the line and the
field (``motion-server: site.toml:12: groups.1.axes: ...``).
"""

from __future__ import annotations

import re
import socket
from collections.abc import Iterator
from pathlib import Path

import pytest

from motion_server import cli, config
from motion_server.config.assembly import Assembly, assemble
from motion_server.safety.passwords import hash_password

SITE = """
data_dir = "{data}"

[modbus]
port = 0

[opcua]
port = 0
data_dir = "{data}/opcua"

[[axes]]
name = "A"
type = "virtual"

[[axes]]
name = "B"

[[groups]]
name = "G1"
axes = ["A", "B"]
"""


@pytest.fixture
def data(tmp_path: Path) -> Path:
    return tmp_path / "data"


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "site.toml"
    path.write_text(text.format(data=tmp_path / "data"))
    return path


def check(path: Path, *options: str) -> str:
    """Run ``motion-server check`` in-process; return its one line of refusal."""
    with pytest.raises(SystemExit) as exc:
        cli.main(["check", str(path), *options])
    message = exc.value.code
    assert isinstance(message, str), message
    assert "\n" not in message and "Traceback" not in message, message
    return message


def line_of(path: Path, text: str, nth: int = 0) -> int:
    lines = path.read_text().splitlines()
    hits = [i + 1 for i, line in enumerate(lines) if line.strip() == text]
    return hits[nth]


def assert_names(message: str, path: Path, line: int, field: str) -> None:
    assert message.startswith(f"motion-server: {path}:{line}: {field}: "), message


def test_a_sound_map_is_checked_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write(tmp_path, SITE)
    assert cli.main(["check", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out == [
        f"{path}: ok: 2 axes, 1 groups, 0 instruction instances, {out[0].split()[-2]} tags"
    ]
    # nothing was left behind by the probes of the data directories
    assert not (tmp_path / "data").exists()


# -- maps that gave tracebacks -------------------------------------------------------------------
def test_an_axis_in_two_groups(tmp_path: Path) -> None:
    path = write(tmp_path, SITE + '\n[[groups]]\nname = "G2"\naxes = ["A"]\n')
    msg = check(path)
    assert_names(msg, path, line_of(path, 'axes = ["A"]'), "groups.1.axes")
    assert "'A' is already in group G1" in msg


def test_an_axis_in_no_group(tmp_path: Path) -> None:
    path = write(tmp_path, SITE.replace('axes = ["A", "B"]', 'axes = ["A"]'))
    msg = check(path)
    assert_names(msg, path, line_of(path, 'name = "B"'), "axes.1.name")
    assert "in no motion group" in msg


def test_no_axes(tmp_path: Path) -> None:
    text = "axes = []\n" + SITE[: SITE.index("[[axes]]")] + '[[groups]]\nname = "G1"\naxes = []\n'
    path = write(tmp_path, text)
    msg = check(path)
    assert_names(msg, path, 1, "axes")
    assert "at least 1 item" in msg


def test_an_explicit_axis_number_clashing_with_an_automatic_one(tmp_path: Path) -> None:
    path = write(
        tmp_path, SITE.replace('[[axes]]\nname = "B"\n', '[[axes]]\nname = "B"\nnumber = 1\n')
    )
    msg = check(path)
    assert_names(msg, path, line_of(path, "number = 1"), "axes.1.number")
    assert "axis number 1 is taken by axis 'A' (numbered by its place in the list)" in msg


def test_deeply_nested_toml(tmp_path: Path) -> None:
    path = write(tmp_path, SITE + "\nextra = " + "[" * 5000 + "]" * 5000 + "\n")
    msg = check(path)
    assert msg == f"motion-server: {path}: invalid TOML: arrays or tables nested too deeply"


def test_an_unwritable_audit_path(tmp_path: Path) -> None:
    blocker = tmp_path / "not-a-directory"
    blocker.write_text("")
    path = write(tmp_path, SITE + f'\n[audit]\nenabled = true\npath = "{blocker}/audit.jsonl"\n')
    msg = check(path)
    assert_names(msg, path, line_of(path, f'path = "{blocker}/audit.jsonl"'), "audit.path")
    assert f"{blocker} is not a directory" in msg


def test_a_host_that_is_not_an_address(tmp_path: Path) -> None:
    path = write(tmp_path, SITE.replace("[modbus]\n", '[modbus]\nhost = "modbus.example"\n'))
    msg = check(path)
    assert_names(msg, path, line_of(path, 'host = "modbus.example"'), "modbus.host")
    assert "is not an IP address" in msg


def test_an_address_of_another_host(tmp_path: Path) -> None:
    # TEST-NET-1 (RFC 5737): an address, but never one of this machine
    path = write(tmp_path, SITE.replace("[modbus]\n", '[modbus]\nhost = "192.0.2.1"\n'))
    msg = check(path)
    assert_names(msg, path, line_of(path, "port = 0"), "modbus.port")
    assert "not an address of this host" in msg


@pytest.fixture
def busy_port() -> Iterator[int]:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        sock.listen(1)
        yield sock.getsockname()[1]


def test_a_modbus_port_in_use(tmp_path: Path, busy_port: int) -> None:
    path = write(tmp_path, SITE.replace("[modbus]\nport = 0", f"[modbus]\nport = {busy_port}"))
    msg = check(path)
    assert_names(msg, path, line_of(path, f"port = {busy_port}"), "modbus.port")
    assert f"Modbus TCP cannot listen on 127.0.0.1:{busy_port}: the port is in use" in msg


def test_a_port_in_use_set_by_an_option_names_the_option(tmp_path: Path, busy_port: int) -> None:
    msg = check(write(tmp_path, SITE), "--opcua-port", str(busy_port))
    assert msg.startswith(f"motion-server: {tmp_path / 'site.toml'}: option --opcua-port: OPC UA")


def test_two_front_ends_on_one_port(tmp_path: Path) -> None:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    text = SITE.replace("[modbus]\nport = 0", f"[modbus]\nport = {port}")
    path = write(tmp_path, text.replace("[opcua]\nport = 0", f"[opcua]\nport = {port}"))
    msg = check(path)
    assert "opcua.port: OPC UA cannot listen" in msg and "the port is in use" in msg


# -- maps that were accepted and should not have been --------------------------------------------
def test_retain_naming_an_unknown_axis(tmp_path: Path) -> None:
    path = write(tmp_path, SITE + '\n[retain]\nenabled = true\naxes = ["A", "C"]\n')
    msg = check(path)
    assert_names(msg, path, line_of(path, 'axes = ["A", "C"]'), "retain.axes")
    assert "unknown axis 'C'" in msg


@pytest.mark.parametrize("entry", ["Nobody", "A.Nothing", "Instructionz"])
def test_an_access_rule_naming_an_unknown_tag(tmp_path: Path, entry: str) -> None:
    rule = f'\n[[modbus.access.rules]]\nnetworks = ["10.0.0.0/8"]\nwrite = ["{entry}"]\n'
    path = write(tmp_path, SITE + rule)
    msg = check(path)
    assert_names(msg, path, line_of(path, f'write = ["{entry}"]'), "modbus.access.rules.0.write")
    assert f"'{entry}' names no folder, owner or tag" in msg


def test_an_access_rule_granting_only_read_only_tags(tmp_path: Path) -> None:
    rule = '\n[[modbus.access.rules]]\nnetworks = ["10.0.0.0/8"]\nwrite = ["G1"]\n'
    msg = check(write(tmp_path, SITE + rule))
    assert "modbus.access.rules.0.write: 'G1' names no writable tag" in msg


WATCHDOG = '\n[[watchdogs]]\nname = "{name}"\ntimeout = 1.0\ngroup = "G1"\n'


@pytest.mark.parametrize(
    ("instances", "name"),
    [
        ("\n[instructions]\nevery_type = true\n", "MAJ_1"),
        ('\n[[instructions.instances]]\nname = "Jog"\ntype = "MAJ"\n', "Jog"),
    ],
)
def test_a_watchdog_named_like_an_instruction_instance(
    tmp_path: Path, instances: str, name: str
) -> None:
    path = write(tmp_path, SITE + instances + WATCHDOG.format(name=name))
    msg = check(path)
    assert_names(msg, path, line_of(path, f'name = "{name}"', -1), "watchdogs.0.name")
    assert f"watchdog name '{name}' is already used by instance" in msg


@pytest.mark.parametrize("value", ["1.5", "1e20", "true", '"1"', "nan"])
def test_an_axis_operand_that_is_no_axis_number(tmp_path: Path, value: str) -> None:
    inst = '\n[[instructions.instances]]\nname = "Jog"\ntype = "MAJ"\n'
    inst += f"operands = {{{{ Axis = {value} }}}}\n"
    path = write(tmp_path, SITE + inst)
    msg = check(path)
    line = line_of(path, f"operands = {{ Axis = {value} }}")
    assert_names(msg, path, line, "instructions.instances.0.operands")
    assert "Axis: " in msg


@pytest.mark.parametrize(
    "cost",
    [
        (2**20, 32, 16),  # more memory than scrypt may use (OpenSSL refuses)
        (2**19, 1, 1),  # n must be below 2**(16 r) (RFC 7914)
        (2**16, 8, 16),  # computable, but a login would take seconds
        (3, 8, 1),  # n not a power of two
    ],
)
def test_a_password_hash_whose_cost_cannot_be_computed(
    tmp_path: Path, cost: tuple[int, int, int]
) -> None:
    n, r, p = cost
    hashed = f"scrypt${n}${r}${p}$c2FsdHNhbHQ=$a2V5a2V5a2V5a2V5a2V5a2V5"
    user = f'\n[[opcua.users]]\nname = "op"\npassword_hash = "{hashed}"\n'
    path = write(tmp_path, SITE + user)
    msg = check(path)
    assert_names(
        msg, path, line_of(path, f'password_hash = "{hashed}"'), "opcua.users.0.password_hash"
    )
    assert "unusable password hash: scrypt" in msg and "a2V5" not in msg


@pytest.mark.parametrize(("n", "r", "p"), [(2**15, 8, 4), (2**16, 4, 4), (2**14, 16, 4)])
def test_the_largest_accepted_costs_are_computed(n: int, r: int, p: int) -> None:
    """At the memory bound (just under 64 MiB with scrypt's own 128·r·(p + 2) bytes) and
    the work bound (n·r·p = 2**20): accepted and computed; one step more is refused."""
    from motion_server.safety.passwords import cost_problem, verify_password

    assert cost_problem(n, r, p) is None
    assert verify_password("secret", hash_password("secret", n=n, r=r, p=p))
    assert cost_problem(2 * n, r, p) is not None
    assert cost_problem(n, r, 2 * p) is not None


AXIS_NUMBERS = [
    "conversion_constant",
    "rollover",
    "max_velocity",
    "max_acceleration",
    "max_deceleration",
    "max_jerk",
    "coast_deceleration",
    "encoder_resolution",
    "following_error_limit",
    "signal_velocity",
    "signal_amplitude",
    "signal_frequency",
]


@pytest.mark.parametrize("value", ["inf", "-inf", "nan", "+inf"])
@pytest.mark.parametrize("field", AXIS_NUMBERS)
def test_non_finite_axis_numbers(tmp_path: Path, field: str, value: str) -> None:
    path = write(tmp_path, SITE.replace('name = "B"\n', f'name = "B"\n{field} = {value}\n'))
    msg = check(path)
    assert_names(msg, path, line_of(path, f"{field} = {value}"), f"axes.1.{field}")


@pytest.mark.parametrize(
    ("setting", "field"),
    [
        ("[controller]\nscale = nan", "controller.scale"),
        ("[controller]\nstatus_log_interval = inf", "controller.status_log_interval"),
        ("[retain]\ninterval = inf", "retain.interval"),
        ("[modbus.access]\nidle_timeout = inf", "modbus.access.idle_timeout"),
        ("[opcua]\npublish_rate_hz = nan", "opcua.publish_rate_hz"),
    ],
)
def test_non_finite_settings(tmp_path: Path, setting: str, field: str) -> None:
    header = setting.splitlines()[0] + "\n"
    text = SITE.replace(header, setting + "\n") if header in SITE else SITE + "\n" + setting + "\n"
    path = write(tmp_path, text)
    msg = check(path)
    assert f": {field}: " in msg and "finite" in msg


@pytest.mark.parametrize(
    ("field", "value", "reason"),
    [
        ("conversion_constant", "1e13", "1e+13 is outside 1e-12..1e+12"),
        ("conversion_constant", "1e-13", "1e-13 is outside 1e-12..1e+12"),
        ("max_velocity", "1e39", "1e+39 is outside 1.175494e-38..3.402823e+38"),
        ("max_velocity", "-1", "-1 is outside 1.175494e-38..3.402823e+38"),
        ("max_deceleration", "5e-324", "4.940656e-324 is outside 1.175494e-38..3.402823e+38"),
        ("max_deceleration", "1e-12", "stopping from max_velocity takes 1e+15 s"),
        # 1,000 mm/s (the default) at 0.1 mm/s²: 10,000 s, beyond the 7,600 s the kernel
        # plans (a group stop from the Maximum Speed would be refused)
        ("max_deceleration", "0.1", "takes 1e+04 s at 0.1; at most 7600 s"),
        ("max_acceleration", "0.001", "reaching max_velocity takes 1e+06 s"),
        ("max_jerk", "1e-3", "reaching the largest rate takes 1e+07 s"),
        ("rollover", "1e-320", "is outside 0 or 1.175494e-38..3.402823e+38"),
    ],
)
def test_limits_beyond_a_real_or_beyond_what_the_kernel_plans(
    tmp_path: Path, field: str, value: str, reason: str
) -> None:
    path = write(tmp_path, SITE.replace('name = "B"\n', f'name = "B"\n{field} = {value}\n'))
    msg = check(path)
    assert_names(msg, path, line_of(path, f"{field} = {value}"), f"axes.1.{field}")
    assert reason in msg


def test_many_problems_are_one_line_each_up_to_twenty(tmp_path: Path) -> None:
    axes = "".join(f'\n[[axes]]\nname = "X{i}"\nmax_velocity = -1\n' for i in range(30))
    path = write(tmp_path, SITE + axes)
    with pytest.raises(config.SiteMapError) as err:
        config.load(path)
    lines = str(err.value).splitlines()
    assert len(lines) == 21
    assert all(
        re.match(rf"{re.escape(str(path))}:\d+: axes\.\d+\.max_velocity: ", ln) for ln in lines[:20]
    )
    assert lines[20] == f"{path}: ... and 10 more problems"


# -- the assembly API ------------------------------------------------------------------------------
def test_assemble_returns_what_run_serves(tmp_path: Path) -> None:
    text = (
        SITE
        + WATCHDOG.format(name="Hmi")
        + (
            '\n[[instructions.instances]]\nname = "Jog"\ntype = "MAJ"\n'
            '\n[audit]\nenabled = true\n\n[retain]\nenabled = true\naxes = ["A"]\n'
            '\n[[opcua.users]]\nname = "op"\n'
            f'password_hash = "{hash_password("pw", n=2**4, r=1)}"\n'
        )
    )
    site = config.load(write(tmp_path, text), environ={})
    out = assemble(site, environ={})
    assert isinstance(out, Assembly)
    assert [a.name for a in out.system.ctl.axes] == ["A", "B"]
    assert list(out.system.instances) == ["Jog"]
    assert "Jog.Speed" in out.tagmap and "Hmi.Heartbeat" in out.tagmap
    assert list(out.watchdogs) == ["Hmi"] and out.watchdogs["Hmi"].ctl is out.system.ctl
    assert [u.name for u in out.users] == ["op"]
    assert out.audit_path == tmp_path / "data" / "audit.jsonl"
    assert out.retain_path == tmp_path / "data" / "retain.json"
    assert not out.restored
    # the probes leave nothing behind
    assert not (tmp_path / "data").exists()
