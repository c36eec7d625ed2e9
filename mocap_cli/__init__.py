"""The command-line edge of mocap: the ``mocap`` console script and its Hydra configs.

Only this package imports Hydra; :mod:`mocap` (the library) never does. The configs live in
``conf/`` at the top of the checkout and ship inside the wheel as ``mocap_cli/conf``
(:data:`CONF_DIR` is whichever of the two this package runs from).

Importing it imports neither Hydra nor OmegaConf (``mocap --help`` stays instant): the config
resolvers are registered by :func:`register_resolvers`, which the first use of :data:`CONF_DIR`
and :mod:`mocap_cli.hydra_edge` call.
"""

# Ctrl-C is honoured from the first moment (mocap_cli/interrupt.py): before anything heavy is imported
from mocap_cli import interrupt as _interrupt  # noqa: I001 (first, on purpose)

if _interrupt.is_program():
    _interrupt.install()

import os  # noqa: E402
from pathlib import Path  # noqa: E402

_HERE = Path(__file__).resolve().parent
#: the Hydra config tree (groups: tracker, data, sweep, hydra/launcher, ...): the package data
#: of an installed wheel, else conf/ of the checkout; read as ``mocap_cli.CONF_DIR``, which
#: registers the resolvers its configs use and the config nodes registered from Python
#: (:mod:`mocap_cli.conf_schema`: the tracker presets, the data sources' defaults)
_CONF_DIR = _HERE / "conf" if (_HERE / "conf").is_dir() else _HERE.parent / "conf"


def source_checkout() -> Path | None:
    """The git checkout the running ``mocap`` comes from (a run's metadata records its
    revision); None for an installed wheel."""
    import mocap

    root = Path(mocap.__file__).resolve().parent.parent
    return root if (root / ".git").exists() else None


def data_dir() -> str:
    """The folder of the bundled sequences (``data/`` of a checkout: the model-mismatch
    benchmark): ``$MOCAP_DATA`` when set, else the ``data/`` folder beside this package when
    it runs from a checkout, else ``data`` (relative to the working directory)."""
    if os.environ.get("MOCAP_DATA"):
        return os.environ["MOCAP_DATA"]
    beside = _HERE.parent / "data"
    return str(beside) if (beside / "mismatch").is_dir() else "data"


def run_hash(override_dirname: str = "") -> str:
    """A short hash naming a run directory by content: of the job's overrides other than
    tracker, data and seed (Hydra's ``hydra.job.override_dirname``, sorted, with those keys
    excluded in conf/tracking.yaml), so the same job gets the same folder in any sweep order."""
    import hashlib

    return hashlib.sha256(str(override_dirname).encode()).hexdigest()[:8]


def register_resolvers() -> None:
    """Register the resolvers of the configs with OmegaConf: ``${mocap_data:}`` in
    conf/data/*.yaml and ``${run_hash:${hydra.job.override_dirname}}`` in conf/tracking.yaml's
    sweep subdir. Called wherever configs are composed: :mod:`mocap_cli.hydra_edge` on import
    (also in the workers of a --multirun, which import the task function's module) and the
    first read of :data:`CONF_DIR`."""
    from omegaconf import OmegaConf

    OmegaConf.register_new_resolver("mocap_data", data_dir, replace=True)
    OmegaConf.register_new_resolver("run_hash", run_hash, replace=True)


def __getattr__(name: str):
    if name == "CONF_DIR":
        from mocap_cli.conf_schema import register_configs

        register_resolvers()
        register_configs()          # the tracker presets and data defaults the configs compose
        return _CONF_DIR
    raise AttributeError(f"module 'mocap_cli' has no attribute {name!r}")
