"""Follow one run from the command line to the report, module by module (issue 32: "a run followed
from the command to the report visits each module once in order").

Runs ``jaxdrift diagnose`` in this process under ``sys.setprofile`` and records, for every call
whose callee is a jaxdrift function, the callee's module. A module is *entered* when a call goes
into it from another module and *left* when the last of its frames returns. A **re-entry** is a
call into a module that was entered and left before: the run comes back to a room it had left.
Returning to a caller is not a re-entry (the caller never left); an import (a module's body
running) is not a visit. Shared helpers are the modules
called from three or more other modules (numerical utilities, records) and the modules that
define the registered causes (the cause registry: ``jaxdrift.diagnosis.registered_causes()``, the
classes' modules and their bases'; each cause owns its behaviour, so every stage that asks a cause
calls into its module, however few stages that are): their re-entries are counted apart. The count
by the three-callers rule alone is printed beside it.

    python benchmarks/validation/module_walk.py RUN.csv --model MODEL.json [--json OUT]

Prints the modules in the order first entered, each module's entries, and the re-entries of the
modules that are not shared helpers (from which module each came back).
"""

from __future__ import annotations

import argparse
import collections
import json
import sys


def registry_modules() -> set[str]:
    """The modules that define the registered causes' classes and their bases."""
    from jaxdrift.diagnosis import registered_causes

    mods = set()
    for causes in registered_causes().values():
        for c in causes:
            mods |= {k.__module__ for k in type(c).__mro__ if k.__module__.startswith("jaxdrift")}
    return mods


def walk(argv):
    from jaxdrift.cli import main

    stack = []  # the jaxdrift module of each live jaxdrift frame, innermost last
    live = collections.Counter()  # live frames per module
    entered, left = [], set()
    reentries = []
    callers = collections.defaultdict(set)

    importing = [0]

    def prof(frame, event, arg):
        if event not in ("call", "return"):
            return
        if frame.f_code.co_name == "<module>":  # an import runs a module's body: not a visit
            importing[0] += 1 if event == "call" else -1
            return
        mod = frame.f_globals.get("__name__", "")
        if importing[0] > 0 or not mod.startswith("jaxdrift"):
            return
        if event == "call":
            caller = stack[-1] if stack else "<command>"
            if caller != mod:
                callers[mod].add(caller)
                if live[mod] == 0:
                    if mod in left:
                        reentries.append((mod, caller))
                        left.discard(mod)
                    entered.append(mod)
            stack.append(mod)
            live[mod] += 1
        else:
            if stack and stack[-1] == mod:
                stack.pop()
                live[mod] -= 1
                if live[mod] == 0:
                    left.add(mod)

    sys.setprofile(prof)
    try:
        rc = main(argv)
    finally:
        sys.setprofile(None)
    by_callers = {m for m, c in callers.items() if len(c) >= 3}
    helpers = by_callers | registry_modules()
    order = list(dict.fromkeys(entered))
    counts = collections.Counter(entered)
    own = [(m, c) for m, c in reentries if m not in helpers]
    return {"exit": rc, "modules": len(order), "entries": len(entered), "reentries": len(reentries),
            "reentries_not_helpers": len(own),
            "reentries_not_called_from_three": sum(1 for m, _ in reentries if m not in by_callers),
            "helpers": sorted(helpers),
            "order": [(m, counts[m]) for m in order],
            "reentered": collections.Counter(f"{m} <- {c}" for m, c in own).most_common()}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run")
    ap.add_argument("--model", default=None)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        args = ["-q", "diagnose", a.run, "--json", f"{tmp}/r.json"]
        if a.model:
            args += ["--model", a.model]
        res = walk(args)
    print(f"exit {res['exit']}: {res['modules']} modules, {res['entries']} entries, {res['reentries']} re-entries "
          f"({res['reentries_not_helpers']} into modules that are not shared helpers; "
          f"{res['reentries_not_called_from_three']} by the three-callers rule alone)")
    for m, n in res["reentered"][:40]:
        print(f"  {n:4d}  {m}")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(res, fh, indent=1)


if __name__ == "__main__":
    main()
