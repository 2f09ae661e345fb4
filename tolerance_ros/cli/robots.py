"""`tolerance-ros robots`: the shipped robot configs, or one robot described before use (`--robot`)."""
from __future__ import annotations

import numpy as np

from ..core.models import load_robot
from ..core.resources import shipped
from ..render.text import table

NAME = "robots"
HELP = "list the shipped robots, or describe one (--robot): its chain, joints and limits, tips, parameters"
ROBOT = False


def add_arguments(p):
    p.add_argument("--robot", help="describe this robot (shipped name or YAML/URDF path) instead of listing")
    p.add_argument("--tip-link", help="URDF robots: the link the chain ends in (the tool)")
    p.add_argument("--base-link", help="URDF robots: the link the chain starts from")


def describe(model) -> dict:
    """The robot as a user needs it before use (SI): kind, chain links, joints with type, limits and unit, the
    URDF's leaf links a tip could be, the error parameters with their units."""
    doc = {"robot": model.name, "kind": type(model).__name__, "dof": model.dof, "parameters": model.n_params,
           "joints": [{"name": n, "type": t, "limits": [float(lo), float(hi)], "unit": "m" if t == "prismatic" else "rad"}
                      for n, t, (lo, hi) in zip(model.joint_names, model.joint_types, model.joint_limits)],
           "parameter_names": list(model.param_names), "parameter_units": list(model.param_units)}
    if hasattr(model, "tip_link"):
        from ..core.models.urdf import _xml, moving_leaves
        doc.update(base_link=model.base_link, tip_link=model.tip_link, source=model.source,
                   leaf_links=moving_leaves(model.pin_model, _xml(model.urdf_text, model.source)),
                   inertials=bool(sum(model.pin_model.inertias[j].mass for j in range(model.pin_model.njoints)) > 0))
    elif getattr(model, "config_path", None):
        doc["source"] = str(model.config_path)
    return doc


def run(args):
    if args.robot:
        model = load_robot(args.robot, args.tip_link, args.base_link)
        doc = describe(model)
        if args.json:
            return doc
        print(f"robot {doc['robot']}: {doc['kind']}, {doc['dof']} joints, {doc['parameters']} error parameters"
              + (f"; from {doc['source']}" if doc.get("source") else ""))
        if "tip_link" in doc:
            inertials = "yes" if doc["inertials"] else "none (elastostatics takes a lumped load)"
            print(f"chain: {doc['base_link']} -> {doc['tip_link']}; leaf links moved by a joint (a --tip-link): "
                  f"{', '.join(doc['leaf_links'])}; inertials: {inertials}")
        print(table(["joint", "type", "lower", "upper", "unit"],
                    [[j["name"], j["type"], f"{j['limits'][0]:.6g}", f"{j['limits'][1]:.6g}", j["unit"]]
                     for j in doc["joints"]]))
        names = np.array(doc["parameter_names"], dtype=object)
        print("error parameters: " + ", ".join(f"{n} [{u}]" for n, u in zip(names, doc["parameter_units"])))
        return None
    if args.tip_link or args.base_link:
        from .common import CLIError
        raise CLIError("--tip-link, --base-link: give them with --robot")
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
