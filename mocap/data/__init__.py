"""Data: the motion library, synthetic multi-view sequences, and loaders for recordings."""
