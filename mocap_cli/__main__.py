"""``python -m mocap_cli <command> ...``: the ``mocap`` console script without installing it."""

import sys

from mocap_cli.main import main

sys.exit(main())
