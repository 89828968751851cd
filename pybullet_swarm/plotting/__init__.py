"""plotting layer."""
