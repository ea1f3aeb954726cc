"""automodal: automated modal parameter estimation from vibration test data."""

__version__ = "0.1.0"

__all__ = ["__version__"]
