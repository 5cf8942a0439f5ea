"""motion-server: a simulated Logix/PLCopen motion controller served over Modbus TCP and OPC UA."""

__version__ = "0.1.0"
