"""Bad and unusual inputs to the command line: each case's exit code and first message.

Writes a run (the road-driven half-car, 4 s at 200 Hz), breaks it in 50 ways, runs the CLI
in-process on each, and writes the table to benchmarks/results/bad-inputs.md (temporary paths
shown as <tmp>). About a minute on 2 cores.

    python benchmarks/validation/bad_inputs.py
"""
import io, os, sys, json, contextlib, shutil, tempfile
from pathlib import Path
import numpy as np
os.environ["MPLBACKEND"] = "Agg"
import jax; jax.config.update("jax_enable_x64", True)
from jaxdrift import cli
from jaxdrift.studies import _rungen as rg

D = tempfile.mkdtemp(prefix="jaxdrift-bad-inputs-")
ROWS = []
cols, _ = rg.make_run([{"cause": "force_noise", "value": 5.0}], duration=4.0, fs=200.0, speed=15.0, road_class="B", seed=3, channels=("beta", "z3"))
cols = {k: np.asarray(v, float) for k, v in cols.items()}
def csv(name, c, names=None, fmt="%.17g", sep=","):
    p = os.path.join(D, name)
    with open(p, "w") as fh:
        fh.write(sep.join(names or list(c)) + "\n")
        np.savetxt(fh, np.column_stack(list(c.values())), delimiter=sep, fmt=fmt)
    return p
good = csv("run.csv", cols)
def edit(name, fn):
    lines = open(good).read().splitlines()
    lines = fn(lines)
    p = os.path.join(D, name); open(p, "w").write("\n".join(lines) + "\n"); return p
def cell(lines, i, j, v):
    c = lines[i].split(","); c[j] = v; lines[i] = ",".join(c); return lines
rep = os.path.join(D, "r.json")
def run(label, argv):
    if os.path.exists(rep): os.unlink(rep)
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            rc = cli.main(argv)
        except SystemExit as e:
            rc = e.code
    msg = [l for l in err.getvalue().replace("\r", "\n").splitlines() if "error" in l or "warning" in l]
    first = (msg[0] if msg else err.getvalue().strip().splitlines()[-1] if err.getvalue().strip() else "")
    row = f"| {label} | {rc} | {first[:230].replace(D, '<tmp>').replace('|', '&#124;')} |"
    ROWS.append(row)
    print(row, flush=True)
J = ["--json", rep]
os.symlink(good, os.path.join(D, "link.json"))
run("--json = the input", ["diagnose", good, "--json", good])
run("--json = symlink to the input", ["diagnose", good, "--json", os.path.join(D, "link.json")])
run("--series = the input", ["diagnose", good, *J, "--series", good])
run("--json and --series the same path", ["diagnose", good, "--json", os.path.join(D, "x.csv"), "--series", os.path.join(D, "x.csv")])
run("--json in a missing folder", ["diagnose", good, "--json", os.path.join(D, "nope", "r.json")])
run("--json in an unwritable folder", ["diagnose", good, "--json", "/sys/r.json"])
run("--plots in an unwritable folder", ["diagnose", good, *J, "--plots", "/sys/p"])
run("--json is a folder", ["diagnose", good, "--json", D])
run("--series with .txt", ["diagnose", good, *J, "--series", os.path.join(D, "s.txt")])
run("forces in kN", ["diagnose", csv("kn.csv", {**cols, "f1": cols["f1"]/1e3, "f2": cols["f2"]/1e3}), *J])
run("forces in daN", ["diagnose", csv("dan.csv", {**cols, "f1": cols["f1"]/10, "f2": cols["f2"]/10}), *J])
run("time in ms", ["diagnose", csv("ms.csv", {**cols, "t": cols["t"]*1e3}), *J])
run("pitch in degrees", ["diagnose", csv("deg.csv", {**cols, "beta": np.degrees(cols["beta"])}), *J])
run("all forces zero", ["diagnose", csv("zero.csv", {**cols, "f1": 0*cols["f1"], "f2": 0*cols["f2"]}), *J])
run("constant z3", ["diagnose", csv("const.csv", {**cols, "z3": 0*cols["z3"] + 0.25}), *J])
sp = cols["f2"].copy(); sp[321] = 1e300
run("one sample 1e300 in f2", ["diagnose", csv("spike.csv", {**cols, "f2": sp}), *J])
run("typo bta for beta", ["diagnose", csv("bta.csv", cols, names=["t","f1","f2","bta","z3"]), *J])
run("Beta (case) for beta", ["diagnose", csv("Beta.csv", cols, names=["t","f1","f2","Beta","z3"]), *J])
run("F2 for f2 (required)", ["diagnose", csv("F2.csv", cols, names=["t","f1","F2","beta","z3"]), *J])
run("duplicate column", ["diagnose", csv("dup.csv", cols, names=["t","f1","f1","beta","z3"]), *J])
run("NaN cell", ["diagnose", edit("nan.csv", lambda l: cell(l, 120, 2, "nan")), *J])
run("empty cell (required)", ["diagnose", edit("empty.csv", lambda l: cell(l, 120, 2, "")), *J])
run("empty cell (optional)", ["diagnose", edit("empty_opt.csv", lambda l: cell(l, 9, 3, "")), *J])
run("inf cell", ["diagnose", edit("inf.csv", lambda l: cell(l, 120, 2, "inf")), *J])
run("text cell 1.2.3", ["diagnose", edit("txt.csv", lambda l: cell(l, 120, 2, "1.2.3")), *J])
run("ragged row", ["diagnose", edit("ragged.csv", lambda l: l[:30] + [l[30] + ",7"] + l[31:]), *J])
run("blank line inside", ["diagnose", edit("blank.csv", lambda l: l[:40] + [""] + l[40:]), *J])
run("time not increasing", ["diagnose", edit("noninc.csv", lambda l: cell(l, 50, 0, l[49].split(",")[0])), *J])
tt = cols["t"].copy(); tt[200:] += 0.001
run("non-uniform time", ["diagnose", csv("nonuni.csv", {**cols, "t": tt}), *J])
run("too short (50 rows)", ["diagnose", csv("short.csv", {k: v[:50] for k, v in cols.items()}), *J])
open(os.path.join(D, "emptyf.csv"), "w").close()
run("empty file", ["diagnose", os.path.join(D, "emptyf.csv"), *J])
open(os.path.join(D, "hdr.csv"), "w").write("t,f1,f2\n")
run("header only", ["diagnose", os.path.join(D, "hdr.csv"), *J])
run("missing file", ["diagnose", os.path.join(D, "nope.csv"), *J])
run("a folder as run", ["diagnose", D, *J])
open(os.path.join(D, "bin.csv"), "wb").write(b"\x89PNG\r\n\x1a\n\x00\xff\xfe" * 50)
run("binary file", ["diagnose", os.path.join(D, "bin.csv"), *J])
open(os.path.join(D, "bad.parquet"), "wb").write(b"not parquet")
run("corrupt parquet", ["diagnose", os.path.join(D, "bad.parquet"), *J])
run("--map to a missing column", ["diagnose", good, *J, "--map", "f1=Fz_FL"])
run("--map with an unknown name", ["diagnose", good, *J, "--map", "bta=beta"])
run("--map malformed", ["diagnose", good, *J, "--map", "f1"])
run("--units wrong unit", ["diagnose", good, *J, "--units", "f1=kg"])
run("--units for a missing column", ["diagnose", good, *J, "--units", "s1=mm"])
run("--fs disagrees with t", ["diagnose", good, *J, "--fs", "250"])
run("--fs negative", ["diagnose", good, *J, "--fs", "-5"])
mdl = os.path.join(D, "m.json"); open(mdl, "w").write('{"mass": 1}')
run("model with unknown key", ["diagnose", good, *J, "--model", mdl])
heavy = os.path.join(D, "heavy.json"); from jaxdrift.io import DEFAULT_MODEL; json.dump({**DEFAULT_MODEL, "m3": 2000.0}, open(heavy, "w"))
run("wrong model (m3 2000 kg)", ["diagnose", good, *J, "--model", heavy])
rng = np.random.default_rng(0); w = rng.normal(0, 0.01, (400, 3)); ta = np.arange(400)/100
run("attitude: wz in deg/s", ["diagnose", csv("att.csv", {"t": ta, "wx": w[:,0], "wy": w[:,1], "wz": np.degrees(w[:,2])*100}), *J])
sys.modules["asammdf"] = None
open(os.path.join(D, "x.mf4"), "wb").write(b"MDF     4.10")
run("MF4 without asammdf (simulated)", ["diagnose", os.path.join(D, "x.mf4"), *J, "--map", "f1=a,f2=b"])
del sys.modules["asammdf"]
run("MF4 that is not MDF", ["diagnose", os.path.join(D, "x.mf4"), *J, "--map", "f1=a,f2=b"])
run("paper --out is a file", ["paper", "--quick", "--out", good])
os.makedirs(os.path.join(D, "po"), exist_ok=True); open(os.path.join(D, "po", "summary.json"), "w").write("{}")
run("paper --params inside --out (summary.json)", ["paper", "--quick", "--out", os.path.join(D, "po"), "--params", os.path.join(D, "po", "summary.json")])
run("pointmass --out unwritable", ["pointmass", "--out", "/sys/x"])
run("ins --out unwritable", ["ins", "--out", "/sys/x"])
run("quaternion-drift --out unwritable", ["quaternion-drift", "--out", "/sys/x"])
run("accel-array --out unwritable", ["accel-array", "--out", "/sys/x"])
# accepted unusual inputs
def tfmt(name, fs, fmt):
    n = int(3*fs); t = 12 + np.arange(n)/fs
    p = os.path.join(D, name)
    with open(p, "w") as fh:
        fh.write("t,f1,f2\n")
        for i in range(n): fh.write(f"{fmt % t[i]},{3825.9 + 50*np.sin(t[i]):.6f},{3825.9 + 40*np.cos(t[i]):.6f}\n")
    return p
from jaxdrift.io import load_run
for label, p in [("1024 Hz, t printed %.9g", tfmt("t1024.csv", 1024.0, "%.9g")), ("300 Hz, t printed %.9g", tfmt("t300.csv", 300.0, "%.9g"))]:
    try:
        r = load_run(p); ROWS.append(f"| {label} (load_run) | accepted | dt = {r.dt:.12g} s; {r.info['notes'][-1][:110]} |")
    except Exception as e:
        ROWS.append(f"| {label} | refused | {e} |")
    print(ROWS[-1])
out = Path(__file__).resolve().parents[1] / "results" / "bad-inputs.md"
with open(out, "w") as fh:
    fh.write("# Bad and unusual inputs (python benchmarks/validation/bad_inputs.py)\n\n| case | exit | first message |\n|---|---|---|\n")
    fh.write("\n".join(ROWS) + "\n")
shutil.rmtree(D, ignore_errors=True)
print("wrote", out)
