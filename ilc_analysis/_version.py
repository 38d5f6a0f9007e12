"""The toolkit's version, in a module of its own so that any module can read it without
importing the package root (``ilc_analysis.__version__`` re-exports it; it equals
``version`` in ``pyproject.toml``)."""

__version__ = "0.1.0"
