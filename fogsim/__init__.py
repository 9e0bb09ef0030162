"""fogsim — labeled images in fog: Koschmieder fog for rendered and real datasets."""

__version__ = "0.1.0"
