"""What every subcommand shares: verbosity (-q/-v), one-line messages, progress bars, the run
options (--map, --units, --fs, --force) and the interrupt handler (Ctrl-C: exit 130, one line)."""

from __future__ import annotations

import os
import signal
import socket
import sys
import threading
import warnings

__all__ = ["VERBOSITY", "set_verbosity", "info", "detail", "warn", "progress", "add_run_options",
           "run_options", "install_interrupt_handler", "route_warnings"]

#: 0 quiet (errors and warnings only), 1 normal, 2 verbose
VERBOSITY = 1
_COMMAND = "jaxdrift"


def set_verbosity(level: int, command: str | None = None) -> None:
    global VERBOSITY, _COMMAND
    VERBOSITY = level
    if command:
        _COMMAND = f"jaxdrift {command}"


def info(msg: str) -> None:
    """A normal message (stderr); silent with -q."""
    if VERBOSITY >= 1:
        print(msg, file=sys.stderr, flush=True)


def detail(msg: str) -> None:
    """A message for -v only."""
    if VERBOSITY >= 2:
        print(msg, file=sys.stderr, flush=True)


def warn(msg: str) -> None:
    """A one-line warning (stderr), shown even with -q."""
    one = " ".join(str(msg).split())
    print(f"{_COMMAND}: warning: {one}", file=sys.stderr, flush=True)


def progress(total=None, desc: str = "", unit: str = "it", enabled: bool = True):
    """A tqdm bar on stderr, off with -q (or ``enabled=False``)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=False,
                disable=not enabled or VERBOSITY < 1, dynamic_ncols=True)


def close_progress_bars() -> None:
    """Clear bars still on screen, so that an error message starts its own line."""
    if "tqdm" in sys.modules:
        from tqdm import tqdm

        for bar in list(getattr(tqdm, "_instances", ())):
            bar.close()


def route_warnings() -> None:
    """Python warnings (numpy's RuntimeWarning included) as one-line messages."""

    def show(message, category, filename, lineno, file=None, line=None):
        where = os.path.basename(filename)
        warn(f"{message} ({category.__name__} in {where}:{lineno})")

    warnings.showwarning = show


def add_run_options(p) -> None:
    """--map, --units, --fs, --strict-time, --force for every command that reads a measured run."""
    g = p.add_argument_group("reading the run (docs/measured-data.md, 'Reading options')")
    g.add_argument("--map", metavar="NAME=COLUMN,...",
                   help="read the contract's columns from other file columns, e.g. f1=Fz_FL,f2=Fz_RL "
                        "(MF4: channel names; ULog: TOPIC:INSTANCE.FIELD, e.g. wx=sensor_gyro:1.x; "
                        "ROS bags: TOPIC.FIELD, e.g. wx=/imu/data.angular_velocity.x; `jaxdrift topics LOG` lists them)")
    g.add_argument("--units", metavar="NAME=UNIT,...",
                   help="units of the file's columns, converted to SI on reading, e.g. f1=kN,f2=kN,t=ms,beta=deg")
    g.add_argument("--fs", type=float, metavar="HZ",
                   help="sample rate [Hz]: checked against t; makes the time base when the file has no t; "
                        "MF4, ULog, bags: the grid rate (default: that of f1, or wx for attitude runs; a faster "
                        "channel is low-pass filtered first)")
    g.add_argument("--strict-time", action="store_true",
                   help="refuse a time column that is not uniform (jitter over 1e-6 of the step, gaps) "
                        "instead of resampling it onto a uniform grid (docs/measured-data.md, 'Time base')")
    g.add_argument("--force", action="store_true",
                   help="go on when the plausibility checks fail (units, dead channels, glitches): "
                        "they become warnings")


def run_options(args) -> dict:
    return {"map": args.map, "units": args.units, "fs": args.fs, "force": args.force,
            "strict_time": bool(getattr(args, "strict_time", False))}


# ----------------------------------------------------------------------------------- Ctrl-C

_EXIT = {signal.SIGINT: 130, signal.SIGTERM: 143}


def _watch(sock) -> None:
    try:
        data = sock.recv(1)
    except OSError:
        return
    signum = data[0] if data else signal.SIGINT
    from ..io._outputs import COMMIT_LOCK, INTERRUPT, remove_pending

    INTERRUPT.set()
    COMMIT_LOCK.acquire()  # never between two renames; held until the process ends
    remove_pending()
    what = "interrupted" if signum == signal.SIGINT else "terminated"
    msg = f"\n{_COMMAND}: {what}; no output was changed except files completed before\n"
    try:
        os.write(2, msg.encode())
    except OSError:
        pass
    os._exit(_EXIT.get(signum, 130))


def install_interrupt_handler() -> None:
    """Ctrl-C (and SIGTERM) exit at once with 130 (143) and one line, from any moment.

    The C-level signal handler writes to a socket; a thread wakes up on it, waits for any rename
    in progress (:data:`jaxdrift.io._outputs.COMMIT_LOCK`), removes temporary files and calls
    ``os._exit``: no Python exception unwinds through JAX/XLA threads (which is what crashed), and
    the exit does not wait for a compilation the main thread may be inside. The main thread, when
    it next runs Python code, finishes a commit in progress and then waits (it never exits 0 after
    an interrupt, and never stops between two renames)."""
    r, w = socket.socketpair()
    w.setblocking(False)
    from ..io._outputs import INTERRUPT, in_commit, park

    def main_thread_handler(*_):
        # the thread acts; the main thread finishes a commit in progress, or else waits for it
        INTERRUPT.set()
        if not in_commit():
            park()

    for s in _EXIT:
        signal.signal(s, main_thread_handler)
    signal.set_wakeup_fd(w.fileno(), warn_on_full_buffer=False)
    threading.Thread(target=_watch, args=(r,), name="jaxdrift-interrupt", daemon=True).start()
    install_interrupt_handler._keep = (r, w)  # keep the sockets alive
    if os.environ.get("JAXDRIFT_TEST_ANNOUNCE"):  # tests of Ctrl-C in the first second
        os.write(2, b"jaxdrift: interrupt handler ready\n")


def guarded(command: str, fn):
    """``(fn(), 0)``; bad input it raises (InputError) becomes a usage error (exit 2), and any other
    failure is ours: ``(None, 1)`` after :func:`internal_failure`."""
    from ..errors import InputError, UsageError

    try:
        return fn(), 0
    except (UsageError, KeyboardInterrupt):
        raise
    except InputError as e:
        raise UsageError(str(e)) from None
    except Exception:  # noqa: BLE001 - anything else is our failure, not the user's
        return None, internal_failure(command)


def internal_failure(command: str, what: str = "", bar=None) -> int:
    """Anything but bad input is our failure, not the user's: the traceback on stderr, exit 1."""
    import traceback

    if bar is not None:
        bar.close()
    print(f"jaxdrift {command}: internal error{' while ' + what if what else ''}:", file=sys.stderr)
    traceback.print_exc()
    return 1
