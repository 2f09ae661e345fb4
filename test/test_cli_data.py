"""`tolerance-ros data`: a public data set from a local folder or a server, each file's sha256 checked (issue 49).
Nothing here reaches the network: the downloads come from a server on 127.0.0.1 serving the shared copy."""
import contextlib
import functools
import http.server
import json
import shutil
import threading

import pytest

from helpers import SHARED_DATA, run_cli as run
from tolerance_ros.core.datasets import DATASETS, sha256

TIAGO = SHARED_DATA / "tiago_mocap"
needs_tiago = pytest.mark.skipif(not TIAGO.is_dir(), reason=f"public data set tiago_mocap not found at {TIAGO}")
FILES = [f.name for f in DATASETS["tiago_mocap"].files]


@contextlib.contextmanager
def served(folder):
    """An HTTP server on 127.0.0.1 serving ``folder`` for the block (its base URL); it answers only there."""
    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass
    handler = functools.partial(Quiet, directory=str(folder))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()
        thread.join(timeout=5)


def test_the_list_names_each_file_with_its_commit_and_sha256(capsys):
    code, out, _ = run(capsys, "data", "list", "--json")
    tiago = {d["name"]: d for d in json.loads(out)["datasets"]}["tiago_mocap"]
    assert code == 0 and [f["file"] for f in tiago["files"]] == FILES
    for f in tiago["files"]:
        assert len(f["commit"]) == 40 and len(f["sha256"]) == 64 and f["commit"] in f["url"]
    assert "BY-NC-ND" in tiago["licence"] and "Apache-2.0" in tiago["licence"]


@needs_tiago
def test_a_local_folder_is_checked_and_copied(capsys, tmp_path):
    code, out, err = run(capsys, "data", "fetch", "tiago_mocap", "--data", TIAGO, "--out", tmp_path, "--json")
    assert code == 0, err
    files = json.loads(out)["files"]
    assert [f["file"] for f in files] == FILES
    for f in DATASETS["tiago_mocap"].files:
        assert sha256(tmp_path / "tiago_mocap" / f.name) == f.sha256
    code, out, _ = run(capsys, "data", "fetch", "tiago_mocap", "--data", TIAGO)       # checked where it is
    assert code == 0 and f"{TIAGO / FILES[0]}: sha256 {DATASETS['tiago_mocap'].files[0].sha256}" in out


@needs_tiago
@pytest.mark.parametrize("damage", ["missing", "changed"])
def test_a_local_folder_with_a_missing_or_changed_file_is_refused_naming_it(capsys, tmp_path, damage):
    copy = tmp_path / "copy"
    shutil.copytree(TIAGO, copy)
    bad = copy / FILES[1]
    if damage == "missing":
        bad.unlink()
    else:
        bad.write_bytes(bad.read_bytes().replace(b"0.1", b"0.2", 1))
    code, _, err = run(capsys, "data", "fetch", "tiago_mocap", "--data", copy, "--out", tmp_path / "out")
    assert code == 2 and str(bad) in err and len(err.strip().splitlines()) == 1
    assert ("missing" if damage == "missing" else "not the published") in err
    assert not (tmp_path / "out" / "tiago_mocap").exists()          # nothing copied from a folder that fails


@needs_tiago
def test_a_download_is_checked_and_a_second_one_keeps_the_files(capsys, tmp_path):
    pytest.importorskip("pooch")
    with served(TIAGO) as url:
        code, out, err = run(capsys, "data", "fetch", "tiago_mocap", "--mirror", url, "--out", tmp_path, "--json")
        assert code == 0, err
        assert [f["from"] for f in json.loads(out)["files"]] == [f"{url}/{n}" for n in FILES]
        for f in DATASETS["tiago_mocap"].files:
            assert sha256(tmp_path / "tiago_mocap" / f.name) == f.sha256
        stamp = (tmp_path / "tiago_mocap" / FILES[0]).stat().st_mtime_ns
        assert run(capsys, "data", "fetch", "tiago_mocap", "--mirror", url, "--out", tmp_path)[0] == 0
        assert (tmp_path / "tiago_mocap" / FILES[0]).stat().st_mtime_ns == stamp     # right sha256: not again


@needs_tiago
def test_a_download_with_another_sha256_is_refused(capsys, tmp_path):
    pytest.importorskip("pooch")
    served_copy = tmp_path / "served"
    shutil.copytree(TIAGO, served_copy)
    (served_copy / FILES[0]).write_text("stamp,x\n1,2\n")
    with served(served_copy) as url:
        code, _, err = run(capsys, "data", "fetch", "tiago_mocap", "--mirror", url, "--out", tmp_path / "out")
    assert code == 2 and f"{FILES[0]}: downloaded from {url}/{FILES[0]}, but" in err
    assert DATASETS["tiago_mocap"].files[0].sha256 in err
    assert not (tmp_path / "out" / "tiago_mocap" / FILES[0]).exists()


def test_a_server_that_does_not_answer_and_pooch_missing_are_one_line(capsys, tmp_path, monkeypatch):
    pytest.importorskip("pooch")
    with served(tmp_path) as url:                                   # an empty folder: 404 for each file
        code, _, err = run(capsys, "data", "fetch", "tiago_mocap", "--mirror", url, "--out", tmp_path / "o")
    assert code == 2 and f"cannot download {url}/{FILES[0]}" in err and len(err.strip().splitlines()) == 1
    import builtins
    real = builtins.__import__

    def no_pooch(name, *args, **kwargs):
        if name == "pooch":
            raise ImportError("No module named 'pooch'")
        return real(name, *args, **kwargs)
    monkeypatch.setattr(builtins, "__import__", no_pooch)
    code, _, err = run(capsys, "data", "fetch", "tiago_mocap", "--out", tmp_path / "o2")
    assert code == 2 and "downloading needs pooch: pip install 'tolerance_ros[data]'" in err and "--data DIR" in err


def test_bad_requests_name_what_is_wrong(capsys, tmp_path):
    for argv, said in ((["fetch", "nosuch", "--out", tmp_path], "data set 'nosuch': not known (known: tiago_mocap)"),
                       (["fetch", "tiago_mocap"], "--out: the folder to download into"),
                       (["fetch"], "name: which data set to fetch?"),
                       (["fetch", "tiago_mocap", "--data", tmp_path / "none"], "is not a folder")):
        code, _, err = run(capsys, "data", *argv)
        assert code == 2 and said in err, err
