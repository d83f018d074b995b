"""rasm.spec."""
