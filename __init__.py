"""mbctl: model-based robot control on Pinocchio (the model) and MuJoCo (the plant)."""

from mbctl.exceptions import ToolkitError

__version__ = "0.1.0"

__all__ = ["ToolkitError", "__version__"]
