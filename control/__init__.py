"""mbctl.control."""
