"""Logix motion instructions, one module per type."""
