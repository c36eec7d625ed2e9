"""Recording sinks. This is the only package that imports ``rerun``."""
