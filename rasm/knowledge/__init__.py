"""rasm.knowledge."""
