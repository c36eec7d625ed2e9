"""The command-line edge of mocap: the ``mocap`` console script and its Hydra configs.

Only this package imports Hydra; :mod:`mocap` (the library) never does. The configs ship as
package data in ``mocap_cli/conf`` (:data:`CONF_DIR`).
"""

# Ctrl-C is honoured from the first moment (mocap_cli/interrupt.py): before anything heavy is imported
from mocap_cli import interrupt as _interrupt  # noqa: I001 (first, on purpose)

if _interrupt.is_program():
    _interrupt.install()

import os  # noqa: E402
from pathlib import Path  # noqa: E402

from omegaconf import OmegaConf  # noqa: E402

#: the Hydra config tree (groups: tracker, data, sweep, hydra/launcher, ...)
CONF_DIR = Path(__file__).resolve().parent / "conf"


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
    beside = CONF_DIR.parent.parent / "data"
    return str(beside) if (beside / "mismatch").is_dir() else "data"


# ${mocap_data:} in conf/data/*.yaml: registered wherever mocap_cli is imported (also in the
# workers of a --multirun, which import the task function's module)
OmegaConf.register_new_resolver("mocap_data", data_dir, replace=True)


def run_hash(override_dirname: str = "") -> str:
    """A short hash naming a run directory by content: of the job's overrides other than
    tracker, data and seed (Hydra's ``hydra.job.override_dirname``, sorted, with those keys
    excluded in conf/tracking.yaml), so the same job gets the same folder in any sweep order."""
    import hashlib

    return hashlib.sha256(str(override_dirname).encode()).hexdigest()[:8]


# ${run_hash:${hydra.job.override_dirname}} in conf/tracking.yaml's sweep subdir
OmegaConf.register_new_resolver("run_hash", run_hash, replace=True)
