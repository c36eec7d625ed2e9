"""Studies: scripts that answer one question each with measurements (index: studies/README.md).
Run them from the checkout with mocap installed: ``python studies/<name>.py ...``."""
