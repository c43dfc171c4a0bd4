"""The experiment's study (docs/experiment.md; issue 42 items 5 and 6): every number of its
tables is measured by a command this script runs and records beside the number.

- ``jm``: the critical mu_s (the least mu_s that traps, mu_k tied at its ratio 0.83) of the
  main job (method 2 in the lab frame), method 1 and the let-go path, per material (Gent J_m
  30, 50, 75, 97.2, 150, and neo-Hookean), at each mesh size (``dynslip window --nodes``),
  with the largest stretch on the path of the run at the measured friction;
- ``depth``: the main job's path pushed 100 to 220 mm, per J_m, at the measured friction:
  trapped, theta_max, rbar_max, the largest stretch;
- ``release``: the release force of the main job's pocket (release_pull_tube.yaml), per N.

Usage: ``python docs/experiment_study.py {jm,depth,release,table} [--only NAME]``; results go
to ``outputs/study/`` (each case in its own folder, rerun only when missing) and
``docs/data/experiment_study/{jm,depth,release}.json`` (what the tables read, a file per part,
so that rerunning one part changes the key of its own tables only); ``table`` prints the markdown
tables of docs/experiment.md.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "outputs" / "study"
DATA = ROOT / "docs" / "data" / "experiment_study"  # a json file per part of the study
PARTS = ("jm", "depth", "release")

MATERIALS = {  # name: --set values
    "gent 30": ["physics.material.model=gent", "physics.material.jm=30"],
    "gent 50": ["physics.material.model=gent", "physics.material.jm=50"],
    "gent 75": ["physics.material.model=gent", "physics.material.jm=75"],
    "gent 97.2": ["physics.material.model=gent", "physics.material.jm=97.2"],
    "gent 150": ["physics.material.model=gent", "physics.material.jm=150"],
    "neo-Hookean": ["physics.material.model=neo_hookean"],
}
#: the paths, their scenario, the mesh sizes of the window search and the materials searched:
#: the main job from N = 150 (below it the mesh does not resolve the tube's rim: no answer)
PATHS = {
    "method 2 (main job)": ("scenarios/method2.yaml", "150,200", tuple(MATERIALS)),
    "method 1": ("scenarios/method1.yaml", "50,100", ("gent 50", "gent 97.2", "neo-Hookean")),
    "let-go": ("scenarios/method2_let_go.yaml", "50,100", ("gent 50", "gent 97.2",
                                                           "neo-Hookean")),
}
WINDOW = ["--lo", "0.4", "--hi", "2.0", "--coarse", "3", "--tol", "0.04"]
#: a finer scan where three points miss a window narrower than their spacing (the let-go path
#: with J_m = 50 traps between about 1.24 and 1.9: 1.2 and 2.0 both miss it)
WINDOW_FOR = {("let-go", "gent 50"): ["--lo", "0.4", "--hi", "2.0", "--coarse", "5", "--tol",
                                      "0.04"]}
MEASURED = ["physics.friction.law=slip_weakening", "physics.friction.mu_s=0.99",
            "physics.friction.mu_k=0.82", "physics.friction.d_c_mm=0.4"]
DEPTHS_MM = (100, 150, 200, 220)


def _slug(*parts) -> str:
    return "_".join(str(p).replace(" ", "").replace("(", "").replace(")", "").replace(".", "p")
                    for p in parts)


def _sets(values) -> list[str]:
    out = []
    for v in values:
        out += ["--set", v]
    return out


def _run(cmd: list[str], log: Path) -> int:
    """Run a ``dynslip ...`` command line with this checkout's package (``python -m
    dynslip.cli``: a worktree at a fixed commit measures that commit), its output in ``log``."""
    import os

    log.parent.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    with log.open("w") as f:
        f.write(" ".join(cmd) + "\n")
        f.flush()
        return subprocess.run([sys.executable, "-m", "dynslip.cli", *cmd[1:]], cwd=ROOT, env=env,
                              stdout=f, stderr=subprocess.STDOUT, check=False).returncode


def _summary(folder: Path) -> dict | None:
    """The summary of a run folder, or of its kept incomplete run (an unknown answer)."""
    for f in [folder, *sorted(folder.parent.glob(folder.name + ".incomplete-*"))[-1:]]:
        if (f / "summary.json").is_file():
            return json.loads((f / "summary.json").read_text())
    return None


def _load() -> dict:
    """The study's records, by part (the parts measured so far)."""
    return {part: json.loads(f.read_text()) for part in PARTS
            if (f := DATA / f"{part}.json").is_file()}


def _save(data: dict) -> None:
    """Each part of ``data`` written whole to its own file (write, then rename)."""
    DATA.mkdir(parents=True, exist_ok=True)
    for part in PARTS:
        if part in data:
            tmp = DATA / f"{part}.json.tmp"
            tmp.write_text(json.dumps(data[part], indent=1, sort_keys=True) + "\n")
            tmp.replace(DATA / f"{part}.json")


def _commit() -> str:
    r = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=ROOT, capture_output=True,
                       text=True, check=False)
    return r.stdout.strip()


def _recorded_commits() -> dict[str, str]:
    """The commit each recorded command was measured at, by command."""
    out: dict[str, str] = {}

    def walk(x):
        if isinstance(x, dict):
            if "command" in x and "commit" in x:
                out[x["command"]] = x["commit"]
            for v in x.values():
                walk(v)

    walk(_load())
    return out


def _commit_of(command: str, ran: bool) -> str:
    """The commit a case was measured at: this checkout's when it ran now, else the one
    recorded beside its command (a reused folder keeps its provenance)."""
    return _commit() if ran else _recorded_commits().get(command, _commit())


def run_run(scenario: str, sets: list[str], name: str) -> dict:
    """One ``dynslip run``: its command and the numbers the tables read."""
    folder = OUT / name
    cmd = ["dynslip", "run", scenario, "--out", str(folder), "--force", *_sets(sets)]
    ran = _summary(folder) is None
    if ran:
        _run(cmd, OUT / f"{name}.log")
    s = _summary(folder) or {}
    ls = s.get("largest_stretch", {})
    command = " ".join(["dynslip", "run", scenario, *_sets(sets)])
    return {
        "command": command,
        "trapped": s.get("trapped"),
        "unknown": s.get("trapped_unknown_reasons"),
        "theta_max": s.get("theta_max"),
        "rbar_max": s.get("rbar_max"),
        "largest_stretch": ls.get("path_max"),
        "largest_stretch_i1_uniaxial": ls.get("path_max_i1_uniaxial"),
        "energy_residual": s.get("energy_balance", {}).get("relative_residual"),
        "release_force_N": s.get("release_force"),
        "commit": _commit_of(command, ran),
    }


def run_window(scenario: str, nodes: str, sets: list[str], name: str, window=None) -> dict:
    """One ``dynslip window --nodes``: the critical mu_s per N."""
    folder = OUT / name
    cmd = ["dynslip", "window", scenario, "--nodes", nodes, *(window or WINDOW), *_sets(sets)]
    found = folder / "window.json"
    ran = not found.is_file()
    if ran:
        _run([*cmd, "--out", str(folder), "--force"], OUT / f"{name}.log")
    w = json.loads(found.read_text()) if found.is_file() else {}
    return {"command": " ".join(cmd), "window": w, "commit": _commit_of(" ".join(cmd), ran)}


def study_jm(only: str | None) -> None:
    data = _load()
    for path, (scenario, nodes, materials) in PATHS.items():
        for mat in materials:
            sets = MATERIALS[mat]
            key = f"{path} | {mat}"
            if only and only not in key:
                continue
            w = run_window(scenario, nodes, sets, _slug("w", path, mat),
                           WINDOW_FOR.get((path, mat)))
            r = run_run(scenario, sets + MEASURED, _slug("r", path, mat))
            data.setdefault("jm", {})[key] = {"window": w, "measured": r}
            _save(data)
            print(key, "done", flush=True)


def study_depth(only: str | None) -> None:
    data = _load()
    for mat in ("gent 50", "gent 97.2"):
        for d in DEPTHS_MM:
            key = f"{d} mm | {mat}"
            if only and only not in key:
                continue
            sets = MATERIALS[mat] + [f"physics.stages.push_down.duration_s={d / 2.0:g}"]
            data.setdefault("depth", {})[key] = run_run("scenarios/method2.yaml", sets,
                                                        _slug("d", d, mat))
            _save(data)
            print(key, "done", flush=True)


def study_release(only: str | None) -> None:
    data = _load()
    for n in (100, 150, 200):
        key = f"N = {n}"
        if only and only not in key:
            continue
        # the pocket at this N (the main job's run at N), then the release from it
        run_run("scenarios/method2.yaml", [f"numerics.nodes={n}"], _slug("pocket", n))
        # relative to the checkout, where the runs start (start_from reads it from there)
        start = (OUT / _slug("pocket", n) / "trajectory.nc").relative_to(ROOT)
        sets = [f"numerics.nodes={n}", f"start_from={start}"]
        data.setdefault("release", {})[key] = run_run("scenarios/release_pull_tube.yaml", sets,
                                                      _slug("rel", n))
        _save(data)
        print(key, "done", flush=True)


def span_geometry(folder: Path) -> dict | None:
    """The pocket's making, read off a run's trajectory: at the deepest push (the sheet's edge
    lowest relative to the ball) the lip (theta_max, rbar_max), the free span's angle from the
    axis where it leaves the lip (degrees; 0: hanging straight down) and the neck (the free
    span's smallest radius below the ball, R); at the end, theta_max and rbar_max."""
    import numpy as np
    import xarray as xr

    runs = [folder, *sorted(folder.parent.glob(folder.name + ".incomplete-*"))[-1:]]
    f = next((r / "trajectory.nc" for r in runs if (r / "trajectory.nc").is_file()), None)
    if f is None:
        return None
    with xr.open_dataset(f) as ds:
        depth = ds["ball_z"].values - ds["z"].values[:, -1]
        i = int(np.argmax(depth))
        rho, z, zb = ds["rho"].values[i], ds["z"].values[i], float(ds["ball_z"].values[i])
        state = ds["state"].values[i]
        on = np.flatnonzero(state > 0)
        out = {"deepest_theta_max": float(ds["theta_max"].values[i]),
               "deepest_rbar_max": float(ds["rbar_max"].values[i])}
        if on.size:
            k = int(on[-1])
            d = np.array([rho[k + 1] - rho[k], z[k + 1] - z[k]])
            out["span_angle_deg"] = float(np.degrees(np.arctan2(abs(d[0]), -d[1])))
            below = (np.arange(rho.size) > k) & (z < zb)
            out["neck_rho"] = float(rho[below].min()) if below.any() else None
        out["end_theta_max"] = float(ds["theta_max"].values[-1])
        out["end_rbar_max"] = float(ds["rbar_max"].values[-1])
    return out


def _ordered(rows: dict) -> list:
    """The study's rows in the order of :data:`PATHS` and :data:`MATERIALS` (the depth's by
    push), whatever order the JSON file keeps."""
    order = [f"{p} | {m}" for p in PATHS for m in MATERIALS]
    order += [f"{d} mm | {m}" for m in MATERIALS for d in DEPTHS_MM]
    return sorted(rows.items(), key=lambda kv: order.index(kv[0]) if kv[0] in order else 999)


def answer_table() -> None:
    """The README's answer: critical mu_s per path and material, and the measured friction's
    answer, with the commit the study ran at."""
    data = _load()
    print("| path | material | critical mu_s at N (mu_k tied, ratio 0.83) | trapped at the "
          "measured 0.99 / 0.82 |")
    print("|---|---|---|---|")
    for key, row in _ordered(data.get("jm", {})):
        path, mat = key.split(" | ")
        m = row["measured"]
        trapped = {True: "**yes**", False: "no", None: "unknown"}[m["trapped"]]
        print(f"| {path} | {mat} | {_crit(row['window']['window'], brackets=True)} | {trapped} |")
    commits = sorted({r["window"]["commit"] for r in data.get("jm", {}).values()})
    print(f"\nMeasured at {', '.join(commits)} by `python docs/experiment_study.py jm` "
          "(each row's command: docs/experiment.md).")


def _crit(w: dict, brackets: bool = False) -> str:
    """The critical mu_s per N of a window.json (``--nodes``: ``critical_mu`` maps N to
    ``{value, err}``), as text: to 3 decimals with the extrapolation where the search made
    one, or (``brackets``) to 2 with each half bracket, ``150: 1.39 +- 0.01; 200: ...``."""
    crit = w.get("critical_mu") or {}
    if "value" in crit:  # one mesh size
        crit = {str(w.get("resolution_check", {}).get("nodes", "")): crit}
    items = sorted(crit.items(), key=lambda kv: int(kv[0]) if kv[0].isdigit() else 0)
    if brackets:
        return "; ".join(f"{n}: {c['value']:.2f} +- {c['err']:.2f}" if c else f"{n}: none"
                         for n, c in items) or "none in [0.4, 2.0]"
    out = [f"{n}: {c['value']:.3f}" if c else f"{n}: none" for n, c in items]
    ex = w.get("extrapolation") or {}
    if ex.get("extrapolable"):
        out.append(f"extrapolated {ex['value']:.3f} +- {ex['err']:.2g}")
    return "; ".join(out)


def _f(v, fmt=".3g"):
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, fmt)


def table() -> None:
    data = _load()
    print("| path | material | critical mu_s by N | trapped at 0.99 / 0.82 | largest stretch "
          "(I1-uniaxial) | command |")
    print("|---|---|---|---|---|---|")
    for key, row in _ordered(data.get("jm", {})):
        path, mat = key.split(" | ")
        m = row["measured"]
        trapped = {True: "yes", False: "no", None: "unknown"}[m["trapped"]]
        print(f"| {path} | {mat} | {_crit(row['window']['window'])} | {trapped} | "
              f"{_f(m['largest_stretch'])} ({_f(m['largest_stretch_i1_uniaxial'])}) | "
              f"`{row['window']['command']}` |")
    print()
    print("| push | material | trapped | bottom: lip theta_max / rbar_max, span from the axis, "
          "neck | end: theta_max / rbar_max | largest stretch (I1-uniaxial) | command |")
    print("|---|---|---|---|---|---|---|")
    for key, m in _ordered(data.get("depth", {})):
        d, mat = key.split(" | ")
        trapped = {True: "yes", False: "no", None: "unknown"}[m["trapped"]]
        g = span_geometry(OUT / _slug("d", int(d.split()[0]), mat)) or {}
        bottom = (f"{_f(g.get('deepest_theta_max'))} / {_f(g.get('deepest_rbar_max'))}, "
                  f"{_f(g.get('span_angle_deg'), '.0f')} deg, {_f(g.get('neck_rho'))} R")
        print(f"| {d} | {mat} | {trapped} | {bottom} | {_f(m['theta_max'])} / "
              f"{_f(m['rbar_max'])} | {_f(m['largest_stretch'])} "
              f"({_f(m['largest_stretch_i1_uniaxial'])}) | `{m['command']}` |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["jm", "depth", "release", "table", "answer"])
    ap.add_argument("--only", default=None, help="run only the cases whose key contains this")
    a = ap.parse_args(argv)
    {"jm": study_jm, "depth": study_depth, "release": study_release,
     "answer": lambda _: answer_table()}.get(a.what, lambda _: table())(a.only)
    return 0


if __name__ == "__main__":
    sys.exit(main())
