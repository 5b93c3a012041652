"""mbctl.sim."""
