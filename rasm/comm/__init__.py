"""rasm.comm."""
