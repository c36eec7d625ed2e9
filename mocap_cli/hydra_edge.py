"""Hydra at the command-line edge: running a Hydra command with overrides, turning its
DictConfig into plain values and objects for :mod:`mocap`, composing a config in-process.

Every Hydra command of ``mocap`` is a module-level function decorated by :func:`command`; the
library (:mod:`mocap`) never sees a DictConfig.
"""

from __future__ import annotations

import contextlib
import difflib
import os
import re
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import hydra
from hydra.core.hydra_config import HydraConfig
from hydra.experimental.callback import Callback
from hydra.types import RunMode
from hydra.utils import instantiate
from omegaconf import DictConfig, OmegaConf, open_dict, read_write

from mocap_cli import CONF_DIR, source_checkout  # (reading CONF_DIR registers the config resolvers)

VERSION_BASE = "1.3"


def _register_schema() -> None:
    """The tracker presets as config nodes (mocap_cli/conf_schema.py)."""
    from mocap_cli import conf_schema

    conf_schema.register_configs()


@contextlib.contextmanager
def _argv(argv: list[str]) -> Iterator[None]:
    old_argv, old_env = sys.argv, os.environ.get("HYDRA_FULL_ERROR")
    sys.argv = argv
    os.environ["HYDRA_FULL_ERROR"] = "1"        # errors reach the caller (mocap_cli.main formats them)
    try:
        yield
    finally:
        sys.argv = old_argv
        if old_env is None:
            os.environ.pop("HYDRA_FULL_ERROR", None)
        else:
            os.environ["HYDRA_FULL_ERROR"] = old_env


#: the run folder locks :class:`RunFolderLock` took for the single run :func:`run_command` is
#: running (released as it returns), and the refusal its task raises instead of running
_run_locks: list[contextlib.ExitStack] = []
_refusals: list[Exception] = []


class _SweepRefused(BaseException):
    """A --multirun refused at its start (another process holds its sweep folder): raised past
    Hydra (which turns a callback's ``Exception`` into a warning and goes on), re-raised by
    :func:`run_command` as the :class:`~mocap.run_folder.lock.RunFolderBusy` it carries."""

    def __init__(self, busy: Exception):
        super().__init__(str(busy))
        self.busy = busy


class RunFolderLock(Callback):
    """One writer per run folder from before Hydra writes into it (a single run's
    ``hydra.run.dir``; ``hydra.callbacks.run_folder_lock`` in conf/tracking.yaml and
    conf/video_check.yaml). Hydra writes ``.hydra/`` (config, hydra.yaml, overrides) and opens
    the job's log file as a job starts, before the task could take the folder's lock
    (:func:`mocap.run_folder.lock.run_lock`): the lock is taken here, as the run starts, and
    held until :func:`run_command` returns (the run re-enters it). Refused (another process
    holds it): Hydra is told to write nothing (no ``.hydra/``, the log on the console only) and
    the task raises the refusal in one line, so the other run's files stay as they are. A
    --multirun holds its sweep folder's lock (``hydra.sweep.dir``) from before Hydra writes
    there until it returns, so a second sweep into the same folder is refused at once, in one
    line, before it writes anything (its jobs take their own folders' locks in the task, as
    before: Hydra writes a job's ``.hydra/`` and log before any callback of the job runs)."""

    @staticmethod
    def _folder(config: DictConfig, key: str) -> Path:
        hydra_config = HydraConfig.instance()
        before = hydra_config.cfg
        hydra_config.set_config(config)     # the ${hydra:...} resolvers of run.dir read it
        try:
            return Path(str(OmegaConf.select(config, key)))   # (${now:} is cached)
        finally:
            hydra_config.cfg = before

    def on_multirun_start(self, config: DictConfig, **kwargs) -> None:
        from mocap.run_folder.lock import RunFolderBusy, run_lock

        if not _run_locks:              # Hydra run by other code than run_command: jobs lock
            return
        try:
            _run_locks[-1].enter_context(run_lock(self._folder(config, "hydra.sweep.dir")))
        except RunFolderBusy as exc:    # Hydra turns a callback's Exception into a warning
            raise _SweepRefused(exc) from None
        except OSError:                 # a folder that cannot be written: the jobs say so
            return

    def on_run_start(self, config: DictConfig, **kwargs) -> None:
        from mocap.run_folder.lock import RunFolderBusy, run_lock

        if not _run_locks:              # Hydra run by other code than run_command: the task locks
            return
        out_dir = self._folder(config, "hydra.run.dir")
        try:
            _run_locks[-1].enter_context(run_lock(out_dir))
        except RunFolderBusy as exc:
            _refusals.append(exc)
            with read_write(config.hydra), open_dict(config.hydra):
                config.hydra.output_subdir = None
                _console_only(config.hydra.job_logging)
        except OSError:                 # a folder that cannot be written: the task says so, in one line
            return


def _console_only(logging_config: DictConfig | None) -> None:
    """Drop the handlers that write a file (a ``filename``) from a logging configuration
    (Hydra's ``job_logging``), and their names from the loggers that use them."""
    handlers = logging_config.get("handlers") if isinstance(logging_config, DictConfig) else None
    if not isinstance(handlers, DictConfig):
        return
    files = [name for name, h in handlers.items() if isinstance(h, DictConfig) and "filename" in h]
    for name in files:
        del handlers[name]
    loggers = logging_config.get("loggers")
    for node in [logging_config.get("root"), *(loggers.values() if isinstance(loggers, DictConfig) else ())]:
        if isinstance(node, DictConfig) and node.get("handlers") is not None:
            node.handlers = [h for h in node.handlers if h not in files]


class _Task:
    """A command's task function; a single run's error is kept and raised after Hydra returns
    (Hydra would add a line of its own before it). A --multirun's job errors are Hydra's."""

    def __init__(self, task: Callable[[DictConfig], object]):
        self.task = task
        self.__module__ = task.__module__       # Hydra names the job (and its .log) after it
        self.__name__ = getattr(task, "__name__", "task")
        self.failure: Exception | None = None

    def __call__(self, cfg: DictConfig) -> object:
        from mocap_cli.quiet import printed_lines_logged

        try:
            if _refusals:                       # refused by RunFolderLock: nothing is done
                raise _refusals.pop()
            with printed_lines_logged():        # the job's <name>.log holds what it printed
                return self.task(cfg)
        except Exception as exc:
            if HydraConfig.get().mode != RunMode.RUN:
                raise
            self.failure = exc
            return None


def run_command(task: Callable[[DictConfig], object], config_name: str, prog: str,
                overrides: list[str] | None) -> int:
    """Run ``task`` under ``@hydra.main`` with the config ``config_name`` of
    :data:`mocap_cli.CONF_DIR` and the command line ``overrides`` (Hydra's own flags included:
    ``--multirun``, ``--cfg job``, ``--help``); errors are raised, not printed."""
    if any(o in ("--help", "-h") for o in overrides or []):
        print(short_help(task, config_name, prog))
        return 0
    _register_schema()
    wrapped = _Task(task)
    main = hydra.main(version_base=VERSION_BASE, config_path=str(CONF_DIR), config_name=config_name)(wrapped)
    with _argv([prog, *(overrides or [])]), contextlib.ExitStack() as locks:
        _run_locks.append(locks)
        try:
            main()
        except _SweepRefused as refused:
            raise refused.busy from None
        except Exception as exc:
            hint = unknown_key_hint(exc, config_name, list(overrides or []), prog)
            if hint is None:
                raise
            raise UnknownKeyError(hint) from exc
        finally:
            _run_locks.remove(locks)
            _refusals.clear()
    if wrapped.failure is not None:
        raise wrapped.failure
    return 0


#: the config groups a short --help lists the options of, with the overrides most runs change
_HELP_GROUPS = ("tracker", "data", "body", "cameras")
_HELP_COMMON = ("frames=N", "seed=N", "threads=N", "init.mode=auto|gt_noise|tracker",
                "recording.enabled=false", "hydra.run.dir=DIR", "--multirun KEY=A,B")


def short_help(task: Callable, config_name: str, prog: str) -> str:
    """A Hydra command's --help: what it does (its module docstring), the options of its config
    groups, common overrides, where the settings live; the full config is one flag away."""
    import textwrap

    doc = (sys.modules[task.__module__].__doc__ or "").strip()
    lines = [doc, ""] if doc else []
    cfg = compose(config_name)
    from mocap_cli.conf_schema import options

    for group in _HELP_GROUPS:
        folder = Path(CONF_DIR) / group
        names = set(options(group)) | {p.stem for p in folder.glob("*.yaml")}
        if group in cfg and names:
            lines += textwrap.wrap(f"{group}=  {', '.join(sorted(names))}", 100, subsequent_indent="    ")
    common = [c for c in _HELP_COMMON
              if c.split("=")[0].split(".")[0] in cfg or c.startswith(("--", "hydra"))]
    conf = Path(CONF_DIR).relative_to(Path(CONF_DIR).parent.parent)
    lines += [""] + textwrap.wrap("common overrides: " + "  ".join(common), 100, subsequent_indent="    ")
    lines += [f"settings: {conf}/{config_name}.yaml (and the groups' folders beside it)",
              f"the full configuration: {prog} --cfg job    Hydra's own help: {prog} --hydra-help"]
    return "\n".join(lines)


class UnknownKeyError(KeyError):
    """An override names a key the config does not have (a user error, with a did-you-mean)."""


_UNKNOWN_KEY = re.compile(r"Could not override '([^']+)'.*Key '([^']+)' is not in struct", re.S)


def unknown_key_hint(exc: BaseException, config_name: str, overrides: list[str],
                     prog: str = "mocap <command>") -> str | None:
    """For Hydra's "Could not override 'frame' ... Key 'frame' is not in struct": one line naming
    the key, the closest keys of its config node ("did you mean frames?") and where the keys are
    listed; None for any other error."""
    match = _UNKNOWN_KEY.search(f"{exc} {exc.__cause__ or ''}")
    if match is None:
        return None
    path = match.group(1)
    parent, _, key = path.rpartition(".")
    try:
        others = [o for o in overrides if o.split("=", 1)[0].lstrip("+~") != path]
        cfg = compose(config_name, [o for o in others if not o.startswith("-")])
        node = OmegaConf.select(cfg, parent) if parent else cfg
        keys = [str(k) for k in node.keys()] if isinstance(node, DictConfig) else []
    except Exception:       # the other overrides do not compose either: no suggestion
        keys = []
    close = difflib.get_close_matches(key, keys, n=3, cutoff=0.6)
    where = f"{parent}." if parent else ""
    hint = f" (did you mean {' or '.join(where + c for c in close)}?)" if close else ""
    return f"unknown setting {path!r}{hint}; `{prog} --cfg job` lists the settings"


def compose(config_name: str, overrides: list[str] | None = None,
            return_hydra_config: bool = False) -> DictConfig:
    """The config ``config_name`` composed with ``overrides`` in-process (no run directory)."""
    from hydra import compose as hydra_compose
    from hydra import initialize_config_dir

    _register_schema()
    with initialize_config_dir(str(CONF_DIR), version_base=VERSION_BASE):
        return hydra_compose(config_name, overrides=list(overrides or []),
                             return_hydra_config=return_hydra_config)


def plain(cfg: DictConfig) -> dict:
    """The resolved config as plain Python values (what metrics.json stores)."""
    return OmegaConf.to_container(cfg, resolve=True)


def output_dir() -> Path:
    """The run directory Hydra chose for this job."""
    return Path(HydraConfig.get().runtime.output_dir)


def parallel_jobs() -> int:
    """Jobs this run shares the machine with: the launcher's n_jobs in a --multirun (joblib), or
    for the submitit launchers with ``cpus_per_task`` set, the cores over cpus_per_task (so that
    ``threads=auto`` is cpus_per_task: on SLURM the job's affinity mask already holds that many
    cores; submitit_local starts every job at once on this machine). -1: one job per core."""
    hc = HydraConfig.get()
    if hc.mode != RunMode.MULTIRUN:
        return 1
    cpus = hc.launcher.get("cpus_per_task")
    if cpus:
        from mocap.threads import available_cores

        return max(1, available_cores() // int(cpus))
    return int(hc.launcher.get("n_jobs", 1) or 1)


_ANNOUNCED: set[str] = set()


def build(node, **kwargs):
    """Instantiate a config node (``_target_`` + arguments); objects go in through a partial,
    since Hydra would turn dataclass arguments into configs.

    This is the user's own command line (the shipped configs, their overrides and the config
    folders they add with ``--config-dir``): a ``_target_`` outside the registry
    (:data:`mocap.presets.TARGETS`) is their own code, e.g. a tracker of their own
    (:mod:`mocap.trackers.contract`), built with a one-line note. Configs read back from files
    (a run folder's metrics.json in rescore and export) never get here: they are checked against
    the registry and refused (:mod:`mocap.run_folder.read`)."""
    from mocap import presets
    from mocap_cli import interrupt

    interrupt.check()           # a Ctrl-C swallowed by a library while it was imported
    plain_node = OmegaConf.to_container(node, resolve=True) if isinstance(node, DictConfig) else node
    target = plain_node.get("_target_") if isinstance(plain_node, dict) else None
    if isinstance(target, str) and target not in presets.TARGETS:
        if target not in _ANNOUNCED:
            _ANNOUNCED.add(target)
            print(f"note: building {target} (your configuration's own code, not a mocap builder)",
                  file=sys.stderr)
    else:
        presets.check_targets(plain_node)
    built = instantiate(node, _partial_=True)(**kwargs) if kwargs else instantiate(node)
    interrupt.check()
    return built


def track_run(cfg: DictConfig, wrap=None, extra=None, check_sequence=None) -> dict | None:
    """:func:`mocap.run_folder.run_tracking` for a composed tracking config (conf/tracking.yaml)
    into the Hydra run directory. check_sequence(seq): raises when the data does not suit the
    command, before any tracking."""
    from mocap.run_folder import run_tracking
    from mocap.threads import resolve_threads

    jobs = parallel_jobs()
    resolve_threads(cfg.get("threads", "auto"), jobs)     # a bad value fails here, before any work

    def make_sequence(body):
        seq = build(cfg.data, body=body)
        if check_sequence is not None:
            check_sequence(seq)
        return seq

    return run_tracking(
        output_dir(), plain(cfg),
        make_body=lambda: build(cfg.body),
        make_sequence=make_sequence,
        make_tracker=lambda **objects: build(cfg.tracker, **objects),
        parallel_jobs=jobs, source=source_checkout(), wrap=wrap, extra=extra,
        overrides=list(HydraConfig.get().overrides.task))
