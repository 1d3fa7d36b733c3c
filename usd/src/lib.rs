//! USD import and export through Python's `usd-core`, embedded with pyo3.
