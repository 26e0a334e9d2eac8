"""flowtex's version (one place; ``flowtex.__version__`` and every cache key read it)."""

__version__ = "0.1.0"
