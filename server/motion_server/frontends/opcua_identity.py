"""Who the OPC UA server says it is, and its certificate.

:func:`identify` gives an asyncua server the product's BuildInfo (ProductName
``motion-server``, ManufacturerName, ProductUri, SoftwareVersion = the package version,
BuildNumber, BuildDate: :mod:`motion_server.identity`), the certificate of the site's
``data_dir`` (issued once and kept: :mod:`.certificates`) and, as ApplicationUri, the URI
that certificate names, so the ApplicationDescription, the ServerArray, the namespace
array and the certificate agree (OPC 10000-4 6.1.3: a client checks the ApplicationUri
against the certificate's SubjectAltName).
"""

from __future__ import annotations

from asyncua import Server

from ..config import OpcUaSection
from ..identity import (
    MANUFACTURER_NAME,
    PRODUCT_NAME,
    PRODUCT_URI,
    build_date,
    build_number,
    software_version,
)
from .certificates import server_certificate


async def identify(server: Server, cfg: OpcUaSection) -> str:
    """BuildInfo, product and application URIs and the certificate of ``cfg.data_dir``
    for ``server`` (after ``init``, before ``start``); returns the application URI."""
    found = server_certificate(cfg.data_dir, cfg.host, "OPC UA")
    server.product_uri = PRODUCT_URI
    server.manufacturer_name = MANUFACTURER_NAME
    await server.set_build_info(
        PRODUCT_URI,
        MANUFACTURER_NAME,
        PRODUCT_NAME,
        software_version(),
        build_number(),
        build_date(),
    )
    await server.set_application_uri(found.application_uri)
    await server.load_certificate(str(found.cert))
    await server.load_private_key(str(found.key))
    return found.application_uri
