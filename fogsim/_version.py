"""fogsim's version, the one place it is written (``pyproject.toml`` reads it statically; every
module that records it imports it from here, so none needs the package's ``__init__``)."""

__version__ = "0.5.0"
