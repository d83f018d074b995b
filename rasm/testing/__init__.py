"""Property-based testing of statecharts and adaptation traces (hypothesis + pytest)."""
