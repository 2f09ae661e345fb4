"""`tolerance-ros data`: the public measurement sets the examples use, fetched from their public source at a
pinned commit, each file's sha256 checked (``core/datasets.py``), or checked in a local folder."""
from __future__ import annotations

from .common import CLIError

NAME = "data"
HELP = "fetch a public measurement set (e.g. tiago_mocap) from its source, each file's sha256 checked; or list them"
ROBOT = False


def add_arguments(p):
    p.add_argument("action", choices=["fetch", "list"], help="fetch a data set, or list the known ones")
    p.add_argument("name", nargs="?", help="the data set (tolerance-ros data list)")
    p.add_argument("--out", metavar="DIR", help="write the files into DIR/NAME/ (fetch)")
    p.add_argument("--data", metavar="FOLDER", help="take the files from this local folder instead of downloading "
                                                    "them (their sha256 checked; copied into --out when given)")
    p.add_argument("--mirror", metavar="URL", help="download from this base URL (one file per name) instead of the "
                                                   "public source")


def run(args):
    from ..core.datasets import DATASETS, DataError, fetch
    if args.action == "list":
        sets = [{"name": d.name, "description": d.description, "source": f"github:{d.repository}",
                 "licence": d.licence, "files": [{"file": f.name, "role": f.role, "commit": f.commit,
                                                  "sha256": f.sha256, "url": d.url(f)} for f in d.files]}
                for d in DATASETS.values()]
        if args.json:
            return {"datasets": sets}
        for s in sets:
            print(f"{s['name']}: {s['description']}\n  source {s['source']}; licence: {s['licence']}")
            for f in s["files"]:
                print(f"  {f['file']} ({f['role']}) at {f['commit'][:12]}, sha256 {f['sha256']}")
        return None
    if not args.name:
        raise CLIError(f"name: which data set to fetch? ({', '.join(sorted(DATASETS))})")
    if args.data and args.mirror:
        raise CLIError("--data, --mirror: a local folder or a base URL, not both")
    if not args.out and not args.data:
        raise CLIError("--out: the folder to download into (the files go into DIR/NAME/); or --data FOLDER to "
                       "check a local copy")
    try:
        files = fetch(args.name, args.out, args.data, args.mirror)
    except DataError as exc:
        raise CLIError(str(exc)) from None
    except OSError as exc:
        raise CLIError(f"--out {args.out}: {exc.strerror or exc}") from None
    if args.json:
        return {"dataset": args.name, "files": files}
    for f in files:
        print(f"{f['path']}: sha256 {f['sha256']} (from {f['from']})")
    return None
