"""The installed package version, read once from the distribution metadata."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("elastocap")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0+unknown"
