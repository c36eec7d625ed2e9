"""Build tooling (not needed at run time): generators of the shipped data.

Everything here runs with the build extra (``bash scripts/install_build_deps.sh``: torch and
anny, imported lazily inside the functions that need them) and writes files the runtime
package only reads (``data/mismatch``, ``data/real_motion``). ``mocap`` never imports it.
"""
