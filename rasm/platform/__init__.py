"""rasm.platform."""
