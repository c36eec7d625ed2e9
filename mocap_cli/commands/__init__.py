"""One module per ``mocap`` command, each with ``main(argv: list[str] | None) -> int``: Hydra
commands take overrides (``main(["tracker=hybrid", "frames=20"])``), the others their flags
(``main(["outputs/track/run", "--format", "bvh"])``). Errors are raised; :mod:`mocap_cli.main`
turns user errors into one line."""
