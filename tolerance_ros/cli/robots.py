"""`tolerance-ros robots`: the shipped robot configs."""
from __future__ import annotations

from ..core.models import load_robot
from ..core.resources import shipped
from ..render.text import table

NAME = "robots"
HELP = "list the shipped robot configs"
ROBOT = False


def add_arguments(p):
    pass


def run(args):
    names = shipped("robots")
    out = []
    for n in names:
        try:
            m = load_robot(n)
            out.append({"name": n, "kind": type(m).__name__, "dof": m.dof, "parameters": m.n_params})
        except Exception as exc:  # a broken shipped file must not hide the others
            out.append({"name": n, "error": str(exc)})
    if args.json:
        return {"robots": out}
    print(table(["robot", "model", "dof", "parameters"],
                [[r["name"], r.get("kind", "error: " + r.get("error", "")), r.get("dof", ""), r.get("parameters", "")]
                 for r in out]))
