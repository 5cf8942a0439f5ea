"""Anonymous access and the None endpoint are honoured on a loopback bind only.

The demo map asks for both "on loopback"; a container overrides the bind host to 0.0.0.0.
Without an explicit ``allow_insecure_remote`` the front-end must then drop both.
"""

from __future__ import annotations

import pytest

from motion_server import config
from motion_server.frontends.opcua import OpcUaFrontend
from motion_server.tagmap import StandaloneHost, TagImage, build_tagmap


def frontend(**opcua: object) -> OpcUaFrontend:
    site = config.load()
    section = site.opcua.model_copy(update=opcua)
    system = site.build()
    image = TagImage(build_tagmap(site), system, StandaloneHost(system))
    return OpcUaFrontend(image, section, users=[])


@pytest.mark.parametrize("host", ["127.0.0.1", "::1", "localhost", "127.0.0.2"])
def test_loopback_keeps_what_the_site_map_asks_for(host: str) -> None:
    fe = frontend(host=host, allow_anonymous=True, allow_none_endpoint=True)
    assert fe.config.allow_anonymous and fe.config.allow_none_endpoint


@pytest.mark.parametrize("host", ["0.0.0.0", "192.0.2.10", "::", "plc.example"])
def test_other_binds_drop_anonymous_and_the_none_endpoint(host: str) -> None:
    fe = frontend(host=host, allow_anonymous=True, allow_none_endpoint=True)
    assert not fe.config.allow_anonymous and not fe.config.allow_none_endpoint


def test_allow_insecure_remote_keeps_them_off_loopback() -> None:
    fe = frontend(host="0.0.0.0", allow_anonymous=True, allow_none_endpoint=True,
                  allow_insecure_remote=True)  # fmt: skip
    assert fe.config.allow_anonymous and fe.config.allow_none_endpoint
