"""Trackers: one interface (``initialize``, ``step(frame) -> Estimate``) for the local
optimizer, the annealed particle filters, the hybrid and the marker tracker."""
