"""rasm.rules."""
