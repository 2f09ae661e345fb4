"""Elastostatics: what loads the joints (a fixed base's inertials, or a humanoid standing on the sole its chain starts
from, with the rest of its posture as recorded) and the chain whose compliances are parameters."""
import numpy as np
import pytest

from tolerance_ros.core.calibration.elastic import (COMPLIANCE, ElasticJoints, Load, _standing_torques, gravity_loads,
                                                    stands_on)
from tolerance_ros.core.models.urdf import URDFChain
from tolerance_ros.testing.example_robots import example_urdf
from tolerance_ros.testing.standing import OTHERS, chain, other_readings


@pytest.fixture(scope="module")
def talos():
    """example-robot-data's whole TALOS, the chain from its left sole to its left gripper."""
    return chain()


def _others(model, n, seed):
    """(names, (n, m) seeded readings) of the right leg and arm."""
    return OTHERS, other_readings(model, n, np.random.default_rng(seed))


def _potential(model, q, others, skip_root=False):
    """The whole robot's potential energy (J) over its sole, gravity along the sole's -z, at chain joints q (dof,):
    every body's mass, the root link's included."""
    import pinocchio as pin
    pm = model.pin_model
    data = pm.createData()
    cfg = model.pinocchio_configuration(q)
    for name, v in zip(*others):
        cfg[pm.idx_qs[pm.getJointId(name)]] = v
    pin.framesForwardKinematics(pm, data, cfg)
    sole = data.oMf[pm.getFrameId(model.base_link)]
    return sum(pm.inertias[j].mass * 9.81 * sole.actInv(data.oMi[j].act(pm.inertias[j].lever))[2]
               for j in range(1 if skip_root else 0, pm.njoints))


def test_a_robot_standing_on_its_sole_loads_each_joint_with_the_force_of_its_whole_weight(talos):
    """The load of each joint of a chain from the sole is minus the gradient of the whole robot's potential energy
    over the sole, the other leg and arm as recorded (they move its centre of mass)."""
    q = talos.sample_joints(3, 2)
    names, values = _others(talos, 3, 5)
    load = Load.for_model(talos)
    assert load.kind == "standing" and stands_on(talos)
    g = load.torques(talos, q, (names, values))
    h = 1e-6
    for i in range(3):
        for j in range(talos.dof):
            e = np.eye(talos.dof)[j] * h
            dV = (_potential(talos, q[i] + e, (names, values[i])) - _potential(talos, q[i] - e, (names, values[i])))
            assert -dV / (2 * h) == pytest.approx(g[i, j], abs=1e-5)
    assert not np.allclose(g, load.torques(talos, q), atol=1.0)      # the posture's rest counts


def test_the_standing_load_of_a_fixed_base_chain_is_pinocchios_generalized_gravity(ur5):
    q = ur5.sample_joints(4, 3)
    assert np.allclose(-_standing_torques(ur5, q), gravity_loads(ur5, q), atol=1e-9)


def test_only_a_link_the_robot_stands_on_gives_the_chain_a_gravity_direction():
    urdf = example_urdf("talos_full_v2.urdf")
    for base, tip, standing in (("right_sole_link", "gripper_right_base_link", True),
                                ("head_2_link", "gripper_left_base_link", False),
                                ("gripper_left_base_link", "left_sole_link", False)):
        model = URDFChain(urdf, tip_link=tip, base_link=base)
        assert stands_on(model) == standing
        assert (Load.for_model(model) is not None) == standing
    sole = URDFChain(urdf, tip_link="gripper_left_base_link", base_link="left_sole_link")
    assert Load.for_model(sole, payload=(2.0, (0.0, 0.0, 0.1))) is None    # a payload needs a fixed base
    assert Load.from_dict(Load("standing").to_dict()) == Load("standing")


def test_the_compliances_columns_are_the_derivatives_of_the_pose(talos):
    q = talos.sample_joints(4, 7)
    names, values = _others(talos, 4, 8)
    model = ElasticJoints(talos, Load.for_model(talos), (q, names, values))
    assert model.n_params == talos.n_params + talos.dof and model.param_kinds[-1] == COMPLIANCE
    assert model.param_units[-1] == "rad/(N m)" and model.param_names[-1] == "arm_left_7_joint.compliance"
    assert np.allclose(model.loads(q), Load.for_model(talos).torques(talos, q, (names, values)))
    rng = np.random.default_rng(0)
    dx = np.r_[rng.normal(0, 1e-3, talos.n_params), rng.normal(0, 1e-4, talos.dof)]
    _, EJ = model.fk_and_jacobian(q, dx)
    for j in [6, 13, 40] + list(model.compliance_columns()):
        h = 1e-7 if j >= talos.n_params else 1e-6
        e = np.zeros(model.n_params)
        e[j] = h
        fd = (model.fk(q, dx + e)[:, :3, 3] - model.fk(q, dx - e)[:, :3, 3]) / (2 * h)
        assert np.allclose(fd, EJ.J[:, :3, j], atol=1e-6 * max(1.0, np.abs(fd).max())), j
    c = dx[talos.n_params:]
    assert np.allclose(model.fk(q, dx), talos.fk(q + c * model.loads(q), dx[:talos.n_params]))


def test_a_held_root_link_takes_its_weight_off_the_joints(talos):
    """A harness or gantry holding the root link (the pelvis): the joints carry the rest of the robot's weight."""
    from tolerance_ros.core.calibration.elastic import HELD
    q = talos.sample_joints(2, 4)
    names, values = _others(talos, 2, 6)
    held = Load(HELD)
    assert Load.from_dict(held.to_dict()) == held and "holds" in held.describe()
    g = held.torques(talos, q, (names, values))
    pm = talos.pin_model
    root = pm.inertias[0].mass
    h = 1e-6
    for i in range(2):
        for j in range(talos.dof):
            e = np.eye(talos.dof)[j] * h
            up, down = (_potential(talos, x, (names, values[i]), skip_root=True) for x in (q[i] + e, q[i] - e))
            assert -(up - down) / (2 * h) == pytest.approx(g[i, j], abs=1e-5)
    assert root > 1.0 and not np.allclose(g, Load("standing").torques(talos, q, (names, values)), atol=1.0)
