"""mbctl.planners."""
