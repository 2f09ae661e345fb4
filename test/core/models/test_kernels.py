"""Compiled kernels: equal to the numpy reference and to pinocchio (1e-12) for D-H and URDF chains."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers import example_urdf, random_dh
from tolerance_ros.core.geometry import rpy_to_matrix
from tolerance_ros.core.models import ModelError, URDFChain, chain_kernels, jit, kernels, load_robot
from tolerance_ros.core.models import jacobian_writers as writers
from tolerance_ros.core.models.dh import SMALL_BATCH

TOL = 1e-12
URDF_CASES = [("ur5_robot.urdf", "tool0"), ("panda.urdf", "panda_hand"), ("panda.urdf", "panda_leftfinger")]
# A chain with a fixed joint between movable ones, a tilted revolute axis and a prismatic joint.
ODD_URDF = """<robot name="odd">
  <link name="l0"/><link name="l1"/><link name="l1b"/><link name="l2"/><link name="l3"/><link name="l4"/>
  <joint name="j1" type="revolute"><parent link="l0"/><child link="l1"/>
    <origin xyz="0.1 -0.2 0.3" rpy="0.3 -0.2 0.1"/><axis xyz="0.3 -0.5 0.8"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="fix" type="fixed"><parent link="l1"/><child link="l1b"/>
    <origin xyz="0 0.05 0.2" rpy="0.4 0 -0.3"/></joint>
  <joint name="j2" type="prismatic"><parent link="l1b"/><child link="l2"/>
    <origin xyz="0.2 0 0" rpy="0 0.5 0"/><axis xyz="0 -1 0"/>
    <limit lower="-0.1" upper="0.3" effort="1" velocity="1"/></joint>
  <joint name="j3" type="continuous"><parent link="l2"/><child link="l3"/>
    <origin xyz="0 0 0.25" rpy="-0.7 0.1 1.2"/><axis xyz="1 0 0"/></joint>
  <joint name="j4" type="continuous"><parent link="l3"/><child link="l4"/>
    <origin xyz="0.1 0 0" rpy="0 0 0.9"/><axis xyz="0 0 -1"/></joint>
</robot>"""


def _with_backend(model, name):
    out = model.with_joint_limits(model.joint_limits)
    out.backend = name
    return out


def _both(model, q, dx=None, jacobian=True):
    """(T, J) from the compiled path and from the numpy reference; J is None without jacobian."""
    out = []
    for name in ("numba", "numpy"):
        T, EJ = _with_backend(model, name).fk_and_jacobian(q, dx, jacobian)
        out.append((T, None if EJ is None else EJ.J))
    return out


def _assert_same(a, b):
    assert a.shape == b.shape
    assert np.abs(a - b).max(initial=0.0) <= TOL


def _dh_pinocchio(model, q, dx=None):
    """(T, J) of a D-H chain from pinocchio's joint frames: each error's line is a joint frame axis."""
    pm, fid = model.to_pinocchio(dx)
    data = pm.createData()
    n, dof = model.n_params // 4, model.dof
    T, J = np.empty((len(q), 4, 4)), np.zeros((len(q), 6, model.n_params))
    for k, qk in enumerate(q):
        pin.framesForwardKinematics(pm, data, qk)
        T[k] = data.oMf[fid].homogeneous
        P = T[k, :3, 3]
        frames = [pin.SE3(model.base)] + [data.oMi[i + 1] for i in range(dof)]
        for i in range(n):
            z, oz = frames[i + 1].rotation[:, 2], frames[i + 1].translation
            before = frames[i + 1] if model.convention == "standard" else frames[i]
            x, ox = before.rotation[:, 0], before.translation
            J[k, :3, i], J[k, :3, n + i] = x, z
            J[k, :, 2 * n + i] = np.r_[np.cross(x, P - ox), x]
            J[k, :, 3 * n + i] = np.r_[np.cross(z, P - oz), z]
    return T, J


def _urdf_pinocchio(chain, q):
    """(T, J) of a URDF chain from pinocchio's joint frames and the URDF origins (rpy) of its joints: the
    shifts along the frame before the origin's rotation, the turns about the axes of the origin's own frame."""
    pm, data = chain.pin_model, chain.pin_model.createData()
    fid = pm.getFrameId(chain.tip_link)
    T, J = np.empty((len(q), 4, 4)), np.zeros((len(q), 6, chain.n_params))
    for k, qk in enumerate(q):
        pin.framesForwardKinematics(pm, data, chain.pinocchio_configuration(qk))
        T[k] = data.oMf[fid].homogeneous
        P = T[k, :3, 3]
        for j, jid in enumerate(chain.chain_ids):
            placed = data.oMi[pm.parents[jid]] * pm.jointPlacements[jid]  # the joint frame before its motion
            W = placed.rotation @ rpy_to_matrix(chain.origin_rpy[j]).T
            G = placed.rotation
            lines = [W[:, 0], W[:, 1], W[:, 2], G[:, 0], G[:, 1], G[:, 2], G @ chain._axes[j]]
            for c, u in enumerate(lines):
                turn = c >= 3 and (c < 6 or chain.joint_types[j] == "revolute")
                J[k, :, 7 * j + c] = np.r_[np.cross(u, P - placed.translation), u] if turn else np.r_[u, 0, 0, 0]
    return T, J


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(["standard", "modified"]), st.sampled_from([1, 3, SMALL_BATCH + 7]),
       st.sampled_from(["none", "shared", "per pose"]))
def test_dh_compiled_equals_numpy_reference(seed, convention, n, dx_kind):
    rng = np.random.default_rng(seed)
    model = random_dh(rng, convention=convention)
    q = model.sample_joints(n, rng)
    dx = {"none": None, "shared": rng.normal(0, 1e-2, model.n_params),
          "per pose": rng.normal(0, 1e-2, (n, model.n_params))}[dx_kind]
    (T, J), (T_ref, J_ref) = _both(model, q, dx)
    _assert_same(T, T_ref)
    _assert_same(J, J_ref)
    (T_fk, J_fk), _ = _both(model, q, dx, jacobian=False)
    assert J_fk is None
    _assert_same(T_fk, T_ref)


@pytest.mark.parametrize("convention", ["standard", "modified"])
@pytest.mark.parametrize("n", [1, SMALL_BATCH + 20])
def test_dh_compiled_equals_pinocchio_with_prismatic_joints(convention, n):
    rng = np.random.default_rng(5 if convention == "standard" else 6)
    model = random_dh(rng, dof=6, convention=convention)
    model = type(model)("mixed", model.a, model.alpha, model.d, model.theta,
                        joint_types=["revolute", "prismatic"] * 3, joint_limits=[[-np.pi, np.pi], [-0.2, 0.3]] * 3,
                        convention=convention, base=model.base, tool=model.tool)
    model.backend = "numba"
    q = model.sample_joints(n, rng)
    dx = rng.normal(0, 1e-2, model.n_params)
    for d in (None, dx):
        T, EJ = model.fk_and_jacobian(q, d)
        T_pin, J_pin = _dh_pinocchio(model, q, d)
        _assert_same(T, T_pin)
        _assert_same(EJ.J, J_pin)


def test_dh_per_pose_errors_equal_pinocchio_pose_by_pose():
    rng = np.random.default_rng(8)
    model = random_dh(rng, dof=5)
    q = model.sample_joints(SMALL_BATCH + 3, rng)
    dx = rng.normal(0, 1e-2, (len(q), model.n_params))
    T, EJ = model.fk_and_jacobian(q, dx)
    for k in (0, 1, len(q) - 1):
        T_pin, J_pin = _dh_pinocchio(model, q[k:k + 1], dx[k])
        _assert_same(T[k:k + 1], T_pin)
        _assert_same(EJ.J[k:k + 1], J_pin)


def test_paper_arm_compiled_equals_numpy_and_pinocchio(gao):
    q = gao.sample_joints(200, 4)
    (T, J), (T_ref, J_ref) = _both(gao, q)
    _assert_same(T, T_ref)
    _assert_same(J, J_ref)
    T_pin, J_pin = _dh_pinocchio(gao, q[:20])
    _assert_same(T[:20], T_pin)
    _assert_same(J[:20], J_pin)


def _urdf_chains():
    chains = [URDFChain(example_urdf(name), tip_link=tip) for name, tip in URDF_CASES]
    return chains + [URDFChain(ODD_URDF)]


@pytest.fixture(scope="module")
def urdf_chains():
    return _urdf_chains()


def test_urdf_cases_cover_prismatic_fixed_and_tilted_joints(urdf_chains):
    assert "prismatic" in urdf_chains[2].joint_types           # panda finger
    odd = urdf_chains[3]
    assert odd.joint_types == ("revolute", "prismatic", "revolute", "revolute")
    assert not np.allclose(odd._fixed[1], np.eye(4))             # the fixed joint before j2
    assert np.count_nonzero(odd._axes[0]) == 3
    # origin rotations of every kind the kernel tells apart: none, about x, y or z alone, any
    kinds = {tuple(np.flatnonzero(c.origin_rpy[j])) for c in urdf_chains for j in range(c.dof)}
    assert {(), (0,), (1,), (2,), (0, 1, 2)} <= kinds


@pytest.mark.parametrize("case", range(4))
@pytest.mark.parametrize("n", [1, SMALL_BATCH + 36])
def test_urdf_compiled_equals_numpy_reference_and_pinocchio(urdf_chains, case, n):
    chain = urdf_chains[case]
    rng = np.random.default_rng(case)
    q = chain.sample_joints(n, rng)
    shared = rng.normal(0, 1e-2, chain.n_params)
    for dx in (None, shared, rng.normal(0, 1e-2, (n, chain.n_params))):
        (T, J), (T_ref, J_ref) = _both(chain, q, dx)
        _assert_same(T, T_ref)
        _assert_same(J, J_ref)
    chain = _with_backend(chain, "numba")
    T, EJ = chain.fk_and_jacobian(q)
    T_pin, J_pin = _urdf_pinocchio(chain, q[:12])
    _assert_same(T[:12], T_pin)
    _assert_same(EJ.J[:12], J_pin)
    T_fk = chain.fk(q)
    _assert_same(T_fk, T)


@pytest.fixture
def choice():
    """The writer choice in force, restored after the test."""
    saved = writers._choice
    yield
    writers._choice = saved


@pytest.mark.parametrize("case", [1, 3])
def test_urdf_every_writer_gives_the_same_bits_as_columns_in_place(urdf_chains, case, choice):
    """A J of LARGE_BYTES or more holds the same bits whichever writer writes it (columns, rows, streaming
    rows), the same as the same poses' J of a small call, and equals the numpy reference; for the Panda and
    the odd chain, without and with per-pose dx."""
    chain = _with_backend(urdf_chains[case], "numba")
    n = writers.LARGE_BYTES // (6 * chain.n_params * 8) + 5
    rng = np.random.default_rng(20 + case)
    q = chain.sample_joints(n, rng)
    for dx in (None, rng.normal(0, 1e-2, (n, chain.n_params))):
        answers = {}
        for name in writers.WRITERS:
            writers.choose_writers(force=name)
            T, EJ = chain.fk_and_jacobian(q, dx)
            assert EJ.J.nbytes >= writers.LARGE_BYTES and writers.writer_for(EJ.J.nbytes) == writers.WRITERS.index(name)
            answers[name] = T, EJ.J
        T, J = answers["columns"]
        for name, (T_w, J_w) in answers.items():
            assert np.array_equal(J_w, J) and np.array_equal(T_w, T), name
        for part in (slice(0, 40), slice(n - 40, n)):
            T_part, EJ_part = chain.fk_and_jacobian(q[part], None if dx is None else dx[part])
            assert EJ_part.J.nbytes < writers.MID_BYTES
            assert np.array_equal(J[part], EJ_part.J) and np.array_equal(T[part], T_part)
        T_ref, EJ_ref = _with_backend(chain, "numpy").fk_and_jacobian(q, dx)
        _assert_same(T, T_ref)
        _assert_same(J, EJ_ref.J)


def _timings(fastest):
    """A fake measurement in which ``fastest`` is the fastest writer for every size class."""
    def measure():
        return {c: {w: (1e-3 if w == fastest else 30e-3) for w in writers.WRITERS} for c in writers.SIZES}
    return measure


@pytest.mark.parametrize("fastest", ["rows", "stream", "columns"])
def test_the_writer_measured_fastest_is_chosen_and_remembered_for_this_cpu_only(tmp_path, fastest, choice,
                                                                                 monkeypatch):
    import json
    monkeypatch.delenv(writers.WRITER_ENV, raising=False)
    path = tmp_path / writers.CHOICE_FILE
    made = writers.choose_writers(_timings(fastest), path)
    assert made["source"] == "measured" and made["writers"] == {c: fastest for c in writers.SIZES}
    assert writers.writer_for(writers.LARGE_BYTES) == writers.WRITERS.index(fastest)
    assert writers.writer_for(writers.MID_BYTES) == writers.WRITERS.index(fastest)
    assert writers.writer_for(writers.MID_BYTES - 1) == 0
    other = next(w for w in writers.WRITERS if w != fastest)

    def not_measured():
        raise AssertionError("measured again, though the choice for this CPU is remembered")
    again = writers.choose_writers(not_measured, path)
    assert again["source"] == "remembered" and again["writers"] == made["writers"]
    doc = json.loads(path.read_text())
    doc["cpu"]["cpu"] = "another CPU"
    path.write_text(json.dumps(doc))
    assert writers.choose_writers(_timings(other), path)["writers"]["large"] == other   # made elsewhere: measured
    path.write_text("{not json")
    assert writers.choose_writers(_timings(fastest), path)["source"] == "measured"


def test_a_forced_writer_is_used_without_measuring_and_a_bad_one_refused(tmp_path, choice, monkeypatch):
    monkeypatch.setenv(writers.WRITER_ENV, "rows")
    forced = writers.choose_writers(_timings("stream"), tmp_path / writers.CHOICE_FILE)
    assert forced["source"] == "forced" and writers.writer_for(writers.LARGE_BYTES) == 1
    assert not (tmp_path / writers.CHOICE_FILE).exists()
    monkeypatch.setenv(writers.WRITER_ENV, "fastest")
    with pytest.raises(ValueError, match=writers.WRITER_ENV):
        writers.choose_writers(_timings("stream"), tmp_path / writers.CHOICE_FILE)


def test_the_writers_are_timed_on_every_size_class(choice):
    times = writers.time_writers(rounds=1)
    assert set(times) == set(writers.SIZES)
    assert all(set(t) == set(writers.WRITERS) and all(0 < v < 5 for v in t.values()) for t in times.values())


def test_urdf_offset_columns_are_pinocchio_joint_jacobian(urdf_chains):
    chain = _with_backend(urdf_chains[1], "numba")
    pm, data = chain.pin_model, chain.pin_model.createData()
    fid = pm.getFrameId(chain.tip_link)
    q = chain.sample_joints(5, 9)
    J = chain.error_jacobian(q).J
    cols = [pm.idx_vs[jid] for jid in chain.chain_ids]
    for k in range(5):
        pin.computeJointJacobians(pm, data, chain.pinocchio_configuration(q[k]))
        pin.updateFramePlacements(pm, data)
        Jp = pin.getFrameJacobian(pm, data, fid, pin.LOCAL_WORLD_ALIGNED)
        _assert_same(J[k][:, 6::7], Jp[:, cols])


def test_every_input_form_uses_one_compiled_signature(gao, urdf_chains):
    """Lists, other dtypes and layouts, read-only arrays, one pose, dx: no new compilation (no stall)."""
    gao = _with_backend(gao, "numba")
    q = gao.sample_joints(4, 1)
    ro = q.copy()
    ro.flags.writeable = False
    ref = gao.fk_and_jacobian(q)[1].J
    for form in (q.tolist(), np.asfortranarray(q), q[:, ::1].T.copy().T, ro, q.astype(object), q.astype(">f8")):
        _assert_same(gao.fk_and_jacobian(form)[1].J, ref)
    _assert_same(gao.fk_and_jacobian(q[0])[1].J, ref[:1])
    gao.fk_and_jacobian(q, np.zeros(gao.n_params))
    gao.fk_and_jacobian(q, np.zeros((4, gao.n_params)), jacobian=False)
    urdf = _with_backend(urdf_chains[0], "numba")
    urdf.fk_and_jacobian(urdf.sample_joints(3, 0).tolist(), np.zeros(urdf.n_params))
    assert len(chain_kernels.dh_chain.signatures) == 1
    assert len(chain_kernels.urdf_chain.signatures) == 1


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_invalid_joints_raise_the_same_messages(gao, backend):
    gao = _with_backend(gao, backend)
    bad = np.zeros((3, 7))
    bad[1, 3] = np.nan
    with pytest.raises(ModelError, match=r"^joints\[1\]\[3\] \(joint4\): not a finite number$"):
        gao.fk_and_jacobian(bad)
    bad[1, 3] = np.inf
    with pytest.raises(ModelError, match=r"^joints\[0\]\[3\] \(joint4\): not a finite number$"):
        gao.fk(bad[1])
    with pytest.raises(ModelError, match=r"shape \(n, 7\) for robot 'gao2023_7dof'.*got \(2, 6\)"):
        gao.fk_and_jacobian(np.zeros((2, 6)))
    with pytest.raises(ModelError, match="expected numbers"):
        gao.fk_and_jacobian([["a"] * 7])
    with pytest.raises(ModelError, match=r"dx: expected shape \(28,\) or \(3, 28\)"):
        gao.fk_and_jacobian(np.zeros((3, 7)), np.zeros(5))
    with pytest.raises(ModelError, match="dx: parameter errors must be finite"):
        gao.fk_and_jacobian(np.zeros((3, 7)), np.full(28, np.nan))


def test_backend_choice_and_fallback(gao, monkeypatch):
    model = _with_backend(gao, "numpy")
    assert model.backend == "numpy" and model._kernels() is None
    with pytest.raises(ModelError, match="backend: expected one of"):
        model.backend = "cuda"
    plain = load_robot("rong2018_3pups")
    plain.compiled = False  # as a mechanism without compiled kernels
    with pytest.raises(ModelError, match="PUPS3 has no compiled kernels"):
        plain.backend = "numba"
    monkeypatch.setattr(kernels, "_unavailable", True)  # as when numba cannot be imported
    fresh = load_robot("gao2023_7dof")
    assert fresh.backend == "numpy"
    with pytest.raises(ModelError, match="numba cannot be imported"):
        fresh.backend = "numba"
    q = gao.sample_joints(3, 0)
    _assert_same(fresh.fk_and_jacobian(q)[1].J, model.fk_and_jacobian(q)[1].J)


def _run_fresh(code, timeout, env=None):
    """Runs ``code`` in a fresh Python process from the repository root (``env``: variables set for it); fails
    with its stderr."""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout,
                         cwd=Path(__file__).resolve().parents[3], env=dict(os.environ, **(env or {})))
    assert out.returncode == 0, out.stderr


def test_models_work_without_numba():
    code = ("import sys; sys.modules['numba'] = None\n"
            "import numpy as np\n"
            "from tolerance_ros.core.models import load_robot\n"
            "m = load_robot('gao2023_7dof')\n"
            "assert m.backend == 'numpy', m.backend\n"
            "assert m.fk_and_jacobian(np.zeros(7))[1].J.shape == (1, 6, 28)\n"
            "assert m.warm_up() < 1.0\n"
            "from tolerance_ros.core.models import warm_up_kernels\n"
            "assert warm_up_kernels() == 0.0\n")
    _run_fresh(code, timeout=120)


def test_warm_up_kernels_readies_the_kernels_named_in_a_fresh_process():
    """What a node calls at start: afterwards no kernel compiles on a request or a new robot_description."""
    code = ("from tolerance_ros.core.models import chain_kernels, pups_kernels, warm_up_kernels, zonotope_kernel\n"
            "every = (chain_kernels.dh_chain, chain_kernels.urdf_chain, zonotope_kernel.zonotope_max,\n"
            "         pups_kernels.pups_solve)\n"
            "assert not any(f.signatures for f in every)\n"
            "assert warm_up_kernels(('urdf',)) > 0.0\n"
            "assert chain_kernels.urdf_chain.signatures and not chain_kernels.dh_chain.signatures\n"
            "warm_up_kernels()\n"
            "assert all(len(f.signatures) == 1 for f in every), [f.signatures for f in every]\n")
    _run_fresh(code, timeout=300)


def test_prime_imports_numba_and_its_registries_without_compiling_a_kernel(tmp_path):
    """What a cold start does while its child compiles: afterwards a family loads with nothing left to import."""
    code = ("import sys\n"
            "from tolerance_ros.core.models import kernels\n"
            "assert 'numba' not in sys.modules\n"
            "kernels.prime(('zonotope',))\n"
            "from tolerance_ros.core.models import zonotope_kernel\n"
            "assert 'numba.np.arraymath' in sys.modules\n"
            "assert 'tolerance_ros.core.models.chain_kernels' not in sys.modules\n"
            "assert not zonotope_kernel.zonotope_max.signatures\n")
    _run_fresh(code, timeout=120, env={"NUMBA_CACHE_DIR": str(tmp_path)})
    assert not list(tmp_path.rglob("*.nbi")), "prime compiled a kernel"


def test_warm_up_loads_the_kernels(gao, urdf_chains):
    assert kernels.warm_up() >= 0.0
    assert _with_backend(urdf_chains[0], "numba").warm_up() >= 0.0
    assert chain_kernels.dh_chain.signatures and chain_kernels.urdf_chain.signatures


def test_sincos_within_an_ulp_of_libm():
    rng = np.random.default_rng(3)
    x = np.concatenate([rng.uniform(-50, 50, 20000), np.arange(-40, 41) * np.pi / 4, [0.0, -0.0, 1e-300],
                        rng.uniform(-1e7, 1e7, 100), [chain_kernels.SINCOS_LIMIT * 1.5, -3e12]])
    s, c = np.empty_like(x), np.empty_like(x)
    chain_kernels.sincos(x, s, c, len(x))
    ulp = np.spacing(1.0)
    assert np.abs(s - np.sin(x)).max() <= ulp and np.abs(c - np.cos(x)).max() <= ulp


def test_private_cache_dir_rejects_a_directory_others_can_write(tmp_path, monkeypatch):
    monkeypatch.setattr(jit.tempfile, "gettempdir", lambda: str(tmp_path))
    path = jit._private_cache_dir()
    assert path == str(tmp_path / f"tolerance_ros-numba-{os.getuid()}")
    assert os.stat(path).st_mode & 0o777 == 0o700
    os.chmod(path, 0o777)
    assert jit._private_cache_dir() is None
