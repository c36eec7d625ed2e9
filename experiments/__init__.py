"""Studies: scripts that answer one question each with measurements (index: experiments/README.md).
Run them from the checkout with mocap installed: ``python experiments/<name>.py ...``."""
