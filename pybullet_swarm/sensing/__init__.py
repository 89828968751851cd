"""sensing layer."""
