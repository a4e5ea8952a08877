"""The package version (one home: the package, its outputs and its checkpoints read it here)."""

__version__ = "0.4.0"
