"""Tag-name clients for motion-server over Modbus TCP and OPC UA."""

__version__ = "0.1.0"
