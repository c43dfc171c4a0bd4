"""The package version and the format version of the files it writes (re-exported by
:mod:`dynslip`); a module of its own so that every layer may read them without importing
the package's public API."""

__version__ = "0.1.0"
FORMAT_VERSION = "1"
