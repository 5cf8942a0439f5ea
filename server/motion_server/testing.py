"""A pytest plugin: a motion-server per test, on free ports, with the manual clock.

Installed with the package (entry point ``pytest11``): every pytest run in an environment
where ``motion-server`` is installed has these fixtures (docs/testing-with-pytest.md):

- ``motion_server``: a server started for the test (``motion-server run`` in a process
  of its own, ``--ready-file``), ephemeral ports, the manual clock, its working
  directory a temporary one; stopped (SIGTERM: the programmed stop) after the test, and a
  server that did not end cleanly fails the test. A :class:`MotionServer`: its ports, its
  log, its tag map, and synchronous helpers to step the clock, read, write and trigger,
  inject an axis fault, save and restore a snapshot and set a communication fault.
- ``motion_client``: a :class:`motion_clients.MotionClient` connected over Modbus TCP to
  that server (an async fixture: needs pytest-asyncio).
- ``motion_site_map``: the site map the server runs; by default the ini option
  ``motion_site_map`` (a path relative to the rootdir), else the embedded demo map.
  Override the fixture in a ``conftest.py`` for a map of your own.
- ``motion_server_factory``: starts more servers (any scope); each is stopped at the end
  of the session at the latest.
- ``motion_server_shared``: with ``motion_server_reuse`` = module or session, the server
  the tests of a module (or session) share (see the fast path below).

Per test, the marker ``@pytest.mark.motion_server(site_map=..., clock="manual", web=True,
opcua=False, args=[...])`` changes how ``motion_server`` is started. OPC UA is served
when the site map says so unless ``opcua=False``; with no user configured the server
creates ``admin`` in its data directory (:attr:`MotionServer.opcua_admin_password`).
``web=True`` serves the web view (when the site map enables it) at
:attr:`MotionServer.web_url`.

The fast path: the ini option ``motion_server_reuse = module`` (or ``session``) starts one
server per module (or per session) and gives each test a fresh controller all the same:
right after start-up the server saves snapshot :data:`RESET_SNAPSHOT`, and before every
test :meth:`MotionServer.reset` puts back the Clock settings the server started with and
restores that snapshot (the controller state bit for bit: axes, instances, faults,
watchdogs, the cycle count). A test with its own ``motion_server`` marker still gets a
server of its own. ``motion_site_map`` is then evaluated once per module or session.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Awaitable, Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import pytest

if TYPE_CHECKING:
    from motion_clients import ClientMap, MotionClient
    from motion_clients.client import Outcome

__all__ = ["MotionServer", "ServerError", "ServerFactory"]

#: seconds a server may take to listen (the scan builds the system, OPC UA its nodes)
START_TIMEOUT = 120.0
#: seconds a server may take to stop after SIGTERM before it is killed
STOP_TIMEOUT = 60.0
#: the lines of the server's log a failure shows
LOG_TAIL = 40
#: the snapshot the fast path saves after start-up and restores before every test
RESET_SNAPSHOT = 0xFFFFFFFF
#: the Clock settings a reset puts back as they were at start (the host's, not the
#: controller's: a snapshot does not hold them)
HOST_SETTINGS = ("Clock.Mode", "Clock.StepCycles", "Clock.CommDelay", "Clock.CommDuration",
                 "Clock.CommClientPort")  # fmt: skip
#: values of ``motion_server_reuse`` and the pytest scope of the shared server
REUSE = {"test": "function", "module": "module", "session": "session"}

T = TypeVar("T")


class ServerError(RuntimeError):
    """The server could not start, or did not end cleanly (the message has its log)."""


class MotionServer:
    """One ``motion-server run`` process; see :meth:`start`."""

    def __init__(
        self,
        proc: subprocess.Popen[bytes],
        workdir: Path,
        site_map: Path | None,
        env: Mapping[str, str],
    ) -> None:
        self.proc = proc
        self.workdir = workdir
        self.site_map = site_map
        self.env = dict(env)
        self.log_file = workdir / "server.log"
        self.ready_file = workdir / "ready.json"
        self.info: dict[str, Any] = {}
        self._map: ClientMap | None = None
        self._stopped = False
        #: the Clock settings at start, once :meth:`keep_initial_state` saved them
        self._initial: dict[str, Any] | None = None

    # -- start and stop -------------------------------------------------------------------
    @classmethod
    def start(
        cls,
        workdir: str | Path,
        site_map: str | Path | None = None,
        *,
        clock: str = "manual",
        opcua: bool | None = None,
        web: bool = False,
        args: Sequence[str] = (),
        env: Mapping[str, str] | None = None,
        timeout: float = START_TIMEOUT,
    ) -> MotionServer:
        """Start ``motion-server run`` in ``workdir`` (its data directories go there) on
        ephemeral ports and wait until every front-end listens; :class:`ServerError`
        with the log when it cannot. ``opcua``: False does not serve OPC UA, None serves
        it when the site map does. ``web``: True serves the web view on an ephemeral port
        when the site map enables it (``[web]``; the demo map does), False never.
        ``args``: more ``motion-server run`` options."""
        work = Path(workdir)
        work.mkdir(parents=True, exist_ok=True)
        site = Path(site_map).resolve() if site_map is not None else None
        environ = dict(os.environ if env is None else env)
        # a site map without data_dir keeps its files (snapshots, retain, audit) in the
        # server's own directory, never in one shared with other servers
        environ["MOTION_SERVER_DATA_DIR"] = str(work.resolve())
        cmd = [sys.executable, "-m", "motion_server.cli", "run"]
        if site is not None:
            cmd.append(str(site))
        cmd += ["--clock", clock, "--modbus-port", "0", "--ready-file", "ready.json"]
        # the helpers step the clock and take snapshots over plain Modbus: admin writes,
        # which a map with users or TLS roles gives plain Modbus only when asked
        cmd += ["--modbus-role", "admin"]
        cmd += ["--no-opcua"] if opcua is False else ["--opcua-port", "0"]
        cmd += ["--web-port", "0"] if web else ["--no-web"]
        cmd += list(args)
        (work / "ready.json").unlink(missing_ok=True)  # left by a server that was killed
        with (work / "server.log").open("ab") as log:
            proc = subprocess.Popen(
                cmd,
                cwd=work,
                env=environ,
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=log,
            )
        server = cls(proc, work, site, environ)
        try:
            server._wait_ready(timeout)
        except BaseException:
            server._terminate()
            raise
        return server

    def _wait_ready(self, timeout: float) -> None:
        give_up = time.monotonic() + timeout
        while not self.ready_file.exists():
            if self.proc.poll() is not None:
                raise ServerError(
                    f"motion-server ended while starting (exit status {self.proc.returncode})"
                    f"\n{self.log_tail()}"
                )
            if time.monotonic() > give_up:
                raise ServerError(
                    f"motion-server did not listen within {timeout:g} s\n{self.log_tail()}"
                )
            time.sleep(0.05)  # another process starting: nothing to step
        self.info = json.loads(self.ready_file.read_text("utf-8"))

    def stop(self, timeout: float = STOP_TIMEOUT, sig: int = signal.SIGTERM) -> int:
        """Send ``sig`` (SIGTERM or SIGINT: the programmed stop of every group), wait, and
        return the exit status (killed after ``timeout`` seconds: then negative)."""
        self._stopped = True
        return self._terminate(timeout, sig)

    def _terminate(self, timeout: float = STOP_TIMEOUT, sig: int = signal.SIGTERM) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        return self.proc.returncode

    def finish(self) -> None:
        """End of the test: stop the server unless the test did; :class:`ServerError`
        when it died meanwhile or did not stop cleanly."""
        if self._stopped:
            return
        died = self.proc.poll()
        code = self.stop()
        if died is not None:
            raise ServerError(
                f"motion-server died during the test (exit status {died})\n{self.log_tail()}"
            )
        if code != 0:
            raise ServerError(
                f"motion-server did not stop cleanly (exit status {code})\n{self.log_tail()}"
            )

    # -- what it is -----------------------------------------------------------------------
    @property
    def pid(self) -> int:
        return self.proc.pid

    @property
    def host(self) -> str:
        """Where clients connect (127.0.0.1 for a server bound to every interface)."""
        host = str(self.info.get("modbus", {}).get("host", "127.0.0.1"))
        return "127.0.0.1" if host in ("", "0.0.0.0", "::") else host

    @property
    def modbus_port(self) -> int:
        return int(self.info.get("modbus", {}).get("port", 0))

    @property
    def opcua_endpoint(self) -> str:
        """The OPC UA endpoint URL ("" when OPC UA is not served)."""
        return str(self.info.get("opcua", {}).get("endpoint", ""))

    @property
    def web_url(self) -> str:
        """The web view's address ("" when it is not served)."""
        return str(self.info.get("web", {}).get("url", ""))

    @property
    def opcua_port(self) -> int:
        return int(self.info.get("opcua", {}).get("port", 0))

    @property
    def opcua_admin_password(self) -> str | None:
        """The password of the ``admin`` the server created (no OPC UA user configured);
        None when it created none."""
        path = Path(self._site().opcua.data_dir)
        path = (path if path.is_absolute() else self.workdir / path) / "admin-password"
        with contextlib.suppress(FileNotFoundError):
            return path.read_text("utf-8").strip()
        return None

    @property
    def map(self) -> ClientMap:
        """The tag map of the server's site (what ``motion-server map`` exports)."""
        if self._map is None:
            from motion_clients import ClientMap

            from .tagmap import build_tagmap, export

            text = export(build_tagmap(self._site()), "json")
            self._map = ClientMap(json.loads(text))
        return self._map

    def _site(self) -> Any:
        from . import config

        return config.load(self.site_map, self.env)

    def log(self) -> str:
        """The server's log so far."""
        return self.log_file.read_text("utf-8", errors="replace")

    def log_tail(self, lines: int = LOG_TAIL) -> str:
        return "\n".join(self.log().splitlines()[-lines:])

    # -- clients --------------------------------------------------------------------------
    def client(self, timeout: float = 10.0) -> MotionClient:
        """A tag-name client over Modbus TCP (not connected yet: ``async with``)."""
        from motion_clients import MotionClient

        return MotionClient.connect(
            self.map, "modbus", self.host, self.modbus_port, timeout=timeout
        )

    def _sync(self, work: Callable[[MotionClient], Awaitable[T]]) -> T:
        async def run() -> T:
            async with self.client() as mc:
                return await work(mc)

        # a thread of its own: works in plain tests and inside a running event loop
        with concurrent.futures.ThreadPoolExecutor(1) as pool:
            return pool.submit(asyncio.run, run()).result()

    def step(self, cycles: int = 1) -> None:
        """Run ``cycles`` cycles (manual clock; answered once they ran)."""
        self._sync(lambda mc: mc.step(cycles))

    def run_for(self, seconds: float) -> int:
        """Advance ``seconds`` of simulated time (whole cycles); the number of cycles."""
        return self._sync(lambda mc: mc.run_for(seconds))

    def read(self, name: str) -> Any:
        """The value of one tag."""
        return self._sync(lambda mc: mc.read(name))

    def read_many(self, names: Sequence[str]) -> dict[str, Any]:
        return self._sync(lambda mc: mc.read_many(names))

    def write(self, name: str, value: Any) -> None:
        self._sync(lambda mc: mc.write(name, value))

    def write_many(self, values: Mapping[str, Any]) -> None:
        self._sync(lambda mc: mc.write_many(values))

    def trigger(self, instance: str, **operands: Any) -> Outcome:
        """The HMI handshake of :meth:`MotionClient.trigger`: operands, trigger, wait for
        success or failure, lower the trigger."""
        return self._sync(lambda mc: mc.trigger(instance, **operands))

    # -- the test bench: faults, snapshots, communication faults ---------------------------
    def inject(self, axis: str, fault: str, held: bool = True) -> None:
        """Hold (or with ``held=False`` remove) an injected fault cause on ``axis``:
        ``fault`` is the tag's suffix, e.g. ``"DriveFault"`` for ``<axis>.InjectDriveFault``
        (``FeedbackLoss``, ``FollowingError``, ``PosHardOvertravel``, ...)."""
        self.write(f"{axis}.Inject{fault}", held)

    def snapshot_save(self, number: int) -> None:
        """Save the controller state as snapshot ``number`` (answered once saved)."""
        self._snapshot(number, "SnapshotSave")

    def snapshot_restore(self, number: int) -> None:
        """Restore snapshot ``number`` (answered once restored; a refusal raises)."""
        self._snapshot(number, "SnapshotRestore")

    def _snapshot(self, number: int, field: str) -> None:
        async def work(mc: MotionClient) -> None:
            await mc.write("Clock.Snapshot", number)
            await mc.write(f"Clock.{field}", True)

        self._sync(work)

    # -- the fast path: one server, a fresh controller per test ---------------------------
    def keep_initial_state(self) -> None:
        """Save the controller as snapshot :data:`RESET_SNAPSHOT` and note the Clock
        settings, for :meth:`reset` (right after start)."""

        async def work(mc: MotionClient) -> dict[str, Any]:
            settings = await mc.read_many(list(HOST_SETTINGS))
            await mc.write("Clock.Snapshot", RESET_SNAPSHOT)
            await mc.write("Clock.SnapshotSave", True)
            return settings

        self._initial = self._sync(work)

    def reset(self) -> None:
        """Back to the state :meth:`keep_initial_state` saw: communication faults off,
        the Clock settings as they were, the controller restored from its snapshot."""
        if self._initial is None:
            raise ServerError("reset() needs keep_initial_state() first")
        initial = self._initial

        async def work(mc: MotionClient) -> None:
            await mc.write("Clock.CommFault", 0)
            await mc.write_many(initial)
            await mc.write("Clock.Snapshot", RESET_SNAPSHOT)
            await mc.write("Clock.SnapshotRestore", True)

        self._sync(work)

    def comm_fault(
        self, kind: str, delay_ms: int = 0, duration_s: float = 0.0, client_port: int = 0
    ) -> None:
        """Delay (``kind`` "delay", ``delay_ms`` per answer) or drop ("drop") the answers to
        the client at TCP port ``client_port`` (0: every client) for ``duration_s`` (0:
        until ``comm_fault("off")``)."""
        mode = {"off": 0, "delay": 1, "drop": 2}[kind]

        async def work(mc: MotionClient) -> None:
            await mc.write("Clock.CommFault", 0)
            if mode:
                await mc.write_many(
                    {
                        "Clock.CommDelay": delay_ms,
                        "Clock.CommDuration": round(duration_s * 1000),
                        "Clock.CommClientPort": client_port,
                    }
                )
                await mc.write("Clock.CommFault", mode)

        self._sync(work)


class ServerFactory:
    """Starts servers in directories of their own; :meth:`close` stops those still
    running."""

    def __init__(self, make_dir: Callable[[], Path], timeout: float = START_TIMEOUT) -> None:
        self._make_dir = make_dir
        self.timeout = timeout
        self.servers: list[MotionServer] = []

    def __call__(
        self,
        site_map: str | Path | None = None,
        *,
        clock: str = "manual",
        opcua: bool | None = None,
        web: bool = False,
        args: Sequence[str] = (),
        env: Mapping[str, str] | None = None,
    ) -> MotionServer:
        server = MotionServer.start(
            self._make_dir(),
            site_map,
            clock=clock,
            opcua=opcua,
            web=web,
            args=args,
            env=env,
            timeout=self.timeout,
        )
        self.servers.append(server)
        return server

    def close(self) -> None:
        for server in self.servers:
            if server.proc.poll() is None:
                server.stop()


# -- the plugin ---------------------------------------------------------------------------
def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addini(
        "motion_site_map",
        "site map (TOML) of the motion_server fixture, relative to the rootdir "
        "(default: the embedded demo map)",
        default="",
    )
    parser.addini(
        "motion_server_reuse",
        "test (default): a server per test; module or session: one server per module or "
        "session, its controller restored to its start-up state before every test",
        default="test",
    )
    parser.addini(
        "motion_server_start_timeout",
        f"seconds a motion_server may take to start (default {START_TIMEOUT:g})",
        default=str(START_TIMEOUT),
    )


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "motion_server(site_map=None, clock='manual', opcua=None, args=()): how the "
        "motion_server fixture starts the server of this test",
    )


@pytest.fixture(scope="session")
def motion_server_factory(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[ServerFactory]:
    """``motion_server_factory(site_map, clock=..., opcua=..., args=..., env=...)`` starts
    a server; those still running are stopped at the end of the session."""
    timeout = float(request.config.getini("motion_server_start_timeout") or START_TIMEOUT)
    factory = ServerFactory(lambda: tmp_path_factory.mktemp("motion-server"), timeout)
    yield factory
    factory.close()


def _reuse(config: pytest.Config) -> str:
    value = str(config.getini("motion_server_reuse") or "test").strip()
    if value not in REUSE:
        raise pytest.UsageError(f"motion_server_reuse = {value!r}: one of {', '.join(REUSE)}")
    return value


def _reuse_scope(fixture_name: str, config: pytest.Config) -> Any:
    """The scope of the shared server and of ``motion_site_map`` (``motion_server_reuse``)."""
    return REUSE[_reuse(config)]


@pytest.fixture(scope=_reuse_scope)
def motion_site_map(request: pytest.FixtureRequest) -> Path | None:
    """The site map of ``motion_server``: the ini option ``motion_site_map``, else None
    (the embedded demo map). Override this fixture for a map of your own (with
    ``motion_server_reuse`` = module or session, at that scope or wider)."""
    value = str(request.config.getini("motion_site_map") or "")
    return request.config.rootpath / value if value else None


@pytest.fixture(scope=_reuse_scope)
def motion_server_shared(
    motion_server_factory: ServerFactory, motion_site_map: Path | None
) -> Iterator[MotionServer]:
    """The server the tests of a module (or session) share (``motion_server_reuse``): its
    start-up state kept as snapshot :data:`RESET_SNAPSHOT`; stopped at the end."""
    server = motion_server_factory(motion_site_map)
    server.keep_initial_state()
    try:
        yield server
    finally:
        server.finish()


@pytest.fixture
def motion_server(
    request: pytest.FixtureRequest,
    motion_server_factory: ServerFactory,
    motion_site_map: Path | None,
) -> Iterator[MotionServer]:
    """A server for this test (see the module): started for it and stopped after it, or,
    with ``motion_server_reuse``, the shared one with its controller as at start-up."""
    marker = request.node.get_closest_marker("motion_server")
    if marker is None and _reuse(request.config) != "test":
        server = request.getfixturevalue("motion_server_shared")
        if server.proc.poll() is not None:
            raise ServerError(
                f"the shared motion-server has died (exit status {server.proc.returncode})"
                f"\n{server.log_tail()}"
            )
        server.reset()
        yield server
        return
    options: dict[str, Any] = dict(marker.kwargs) if marker is not None else {}
    site_map = options.pop("site_map", motion_site_map)
    server = motion_server_factory(site_map, **options)
    try:
        yield server
    finally:
        server.finish()


def _client_fixture() -> Any:
    """``motion_client``: async, with pytest-asyncio; without it, a fixture that says so."""
    try:
        import pytest_asyncio
    except ImportError:  # the rest of the plugin works without it

        @pytest.fixture(name="motion_client")
        def missing() -> None:
            pytest.fail(
                "the motion_client fixture needs pytest-asyncio "
                "(pip install 'motion-server[pytest]')",
                pytrace=False,
            )

        return missing

    @pytest_asyncio.fixture(name="motion_client", loop_scope="function")
    async def client(motion_server: MotionServer) -> Any:
        """A :class:`motion_clients.MotionClient` connected over Modbus TCP to
        ``motion_server`` (closed after the test)."""
        async with motion_server.client() as mc:
            yield mc

    return client


motion_client = _client_fixture()
