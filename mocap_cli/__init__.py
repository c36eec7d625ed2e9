"""The command-line edge of mocap: the ``mocap`` console script and its Hydra configs.

Only this package imports Hydra; :mod:`mocap` (the library) never does. The configs ship as
package data in ``mocap_cli/conf`` (:data:`CONF_DIR`).
"""

from pathlib import Path

#: the Hydra config tree (groups: tracker, data, sweep, hydra/launcher, ...)
CONF_DIR = Path(__file__).resolve().parent / "conf"
