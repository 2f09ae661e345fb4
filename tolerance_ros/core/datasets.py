"""Public measurement sets, fetched from their public source rather than kept in the repository: each file at
a pinned commit with its sha256, so that what is read is what was published.

``fetch(name, out)`` downloads a set's files into ``out/<name>/`` with pooch (an optional dependency: the
``data`` extra), each checked against its sha256 (a file already there with the right sha256 is kept, any
other is downloaded again); ``mirror`` takes them from another base URL (a folder served over HTTP, one file
per name); ``data`` takes them from a local folder instead, checking the sha256 of each file found there.
``DataError`` names the file and what is wrong (missing, another sha256, a download that failed).
"""
from __future__ import annotations

import hashlib
import shutil
from dataclasses import dataclass
from pathlib import Path


class DataError(ValueError):
    """A data set that cannot be had as published; the message names the file and why."""


@dataclass(frozen=True)
class DataFile:
    name: str          # the file's name in the set's folder
    path: str          # its path in the source repository
    commit: str        # the commit it is taken at
    sha256: str
    role: str = ""


@dataclass(frozen=True)
class DataSet:
    name: str
    description: str
    repository: str    # owner/name of the public source
    licence: str
    files: tuple

    def url(self, f: DataFile) -> str:
        """The file's public URL at its pinned commit."""
        return f"https://raw.githubusercontent.com/{self.repository}/{f.commit}/{f.path}"


_MOCAP = "examples/tiago/data/calibration/mocap/"
DATASETS = {
    "tiago_mocap": DataSet(
        "tiago_mocap",
        "a PAL TIAGo arm measured by Qualisys motion capture at static postures on two days (November 2021), and "
        "the URDF its publishers calibrate (FIGAROH examples)",
        "thanhndv212/figaroh-examples",
        "the CSV files: Apache-2.0 (Thanh Nguyen / CNRS / Toward); tiago_48_schunk.urdf: Creative Commons "
        "BY-NC-ND 3.0 (PAL Robotics, its own header): not redistributed here, and a calibrated URDF made from it "
        "falls under its licence",
        (DataFile("qualisys_2021-11-30_static_postures.csv", _MOCAP + "qualisys_2021-11-30_static_postures.csv",
                  "987dc8419b053706f41466498038f1b168401bfc",
                  "b6c0051e20c6a077a6d2cf64ba912996945bbb85d6860cd6cea7d8ff65b1b9af", "training day"),
         DataFile("qualisys_2021-11-26_static_postures.csv", _MOCAP + "qualisys_2021-11-26_static_postures.csv",
                  "7dff77ade6ee22b66e44fbb55bc889692e68fc17",
                  "7c986df711757c4d31d8bb6db34b354f72318a78673dac280fd3a14abc5460a0", "validation day"),
         DataFile("tiago_48_schunk.urdf", "examples/tiago/urdf/tiago_48_schunk.urdf",
                  "b45a16e8e95ccd643d110083f2263adc97396f3a",
                  "e4412357e3ea141097acc835d81c4ac477f889ad99b05d2a9818ed9cdf9d12b6", "robot model"))),
}


def dataset(name: str) -> DataSet:
    """The registered data set ``name``; DataError naming the known ones otherwise."""
    if name not in DATASETS:
        raise DataError(f"data set {name!r}: not known (known: {', '.join(sorted(DATASETS))})")
    return DATASETS[name]


def sha256(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def fetch(name: str, out=None, data=None, mirror: str | None = None) -> list:
    """[{file, path, sha256, from}] of the set's files, each checked: from the local folder ``data`` (copied into
    ``out/<name>/`` when ``out`` is given, else only checked where they are), or downloaded into ``out/<name>/``
    from their public source (or from ``mirror``, a base URL) with pooch."""
    ds = dataset(name)
    if data is not None:
        return _from_folder(ds, Path(data), None if out is None else Path(out) / name)
    if out is None:
        raise DataError("out: the folder to download into is required (or give a local folder with the files)")
    try:
        import pooch
    except ImportError:
        raise DataError("downloading needs pooch: pip install 'tolerance_ros[data]' (or pip install pooch); or take "
                        "the files from a local folder that has them (--data DIR)") from None
    folder = Path(out) / name
    folder.mkdir(parents=True, exist_ok=True)
    logger = pooch.get_logger()
    level = logger.level
    logger.setLevel("WARNING")   # its own 'Downloading ...' lines: the command says what it fetched
    try:
        return _download(pooch, ds, folder, mirror)
    finally:
        logger.setLevel(level)


def _download(pooch, ds: DataSet, folder: Path, mirror) -> list:
    done = []
    for f in ds.files:
        url = f"{mirror.rstrip('/')}/{f.name}" if mirror else ds.url(f)
        try:
            path = pooch.retrieve(url, known_hash=f"sha256:{f.sha256}", fname=f.name, path=folder,
                                  progressbar=False)
        except ValueError as exc:        # pooch: the downloaded file's hash is another
            raise DataError(f"{f.name}: downloaded from {url}, but {_first_line(exc)}") from None
        except Exception as exc:          # the network, the server: requests' and pooch's errors
            raise DataError(f"{f.name}: cannot download {url}: {type(exc).__name__}: {_first_line(exc)}") from None
        done.append({"file": f.name, "path": str(path), "sha256": f.sha256, "from": url})
    return done


def _from_folder(ds: DataSet, data: Path, folder: Path | None) -> list:
    if not data.is_dir():
        raise DataError(f"data: {data} is not a folder")
    found = []
    for f in ds.files:
        src = data / f.name
        if not src.is_file():
            raise DataError(f"{src}: missing (data set {ds.name} has {', '.join(x.name for x in ds.files)})")
        got = sha256(src)
        if got != f.sha256:
            raise DataError(f"{src}: sha256 {got}, not the published {f.sha256} (another version of {f.name}, or "
                            f"damaged)")
        found.append((f, src))
    done = []
    for f, src in found:
        path = src
        if folder is not None:
            folder.mkdir(parents=True, exist_ok=True)
            path = folder / f.name
            if path.resolve() != src.resolve():
                shutil.copyfile(src, path)
        done.append({"file": f.name, "path": str(path), "sha256": f.sha256, "from": str(src)})
    return done


def _first_line(exc) -> str:
    return (str(exc).strip().splitlines() or [""])[0][:300]
