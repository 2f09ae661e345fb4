"""Calibration from contact on real data: FIGAROH's TALOS table-contact training sessions (../shared/data; skipped where
absent), the chain from the standing foot's sole to the gripper of example-robot-data's talos_full_v2.urdf, the three
fingertips flush on the table. The fits reach the optimum scipy finds on the same objective, with the same unknowns
held; what is held, and why."""
import numpy as np
import pytest

from tolerance_ros.testing import talos_contact as tc

pytestmark = pytest.mark.skipif(not tc.available(), reason=f"the TALOS table-contact sessions are not in {tc.DATA}")


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    """{side: (model, ContactData, nominal offsets (3, 3) m)} of both training sessions, read as calibrate reads them."""
    from tolerance_ros.core.accuracy.io.contact_csv import read_contacts
    from tolerance_ros.core.calibration.contact_campaign import contact_data
    from tolerance_ros.core.models.urdf import URDFChain
    from tolerance_ros.testing.example_robots import example_urdf
    out = {}
    for side in tc.SESSIONS:
        base, tip = tc.chain(side)
        model = URDFChain(example_urdf(tc.URDF), tip_link=tip, base_link=base)
        path = tc.write_campaign(side, tmp_path_factory.mktemp(side) / f"{side}.csv")
        offsets = {k: np.array(v) * 1e-3 for k, v in tc.FINGERTIPS.items()}
        data, nominal, _ = contact_data(model, read_contacts(path, model.joint_names), offsets)
        out[side] = (model, data, nominal)
    return out


def _free(model, data, f) -> np.ndarray:
    """The unknowns fit ``f`` left free: neither a held parameter nor a target held at its nominal place."""
    held = np.zeros(f.layout.n, bool)
    held[model.param_index(f.held)] = True
    names = f.layout.names(model, data)
    held[[names.index(f"target {k}") for k, w in f.targets_why.items() if not w["fitted"]]] = True
    return np.flatnonzero(~held)


@pytest.mark.parametrize("side", list(tc.SESSIONS))
@pytest.mark.parametrize("candidate", [("joint-offsets", None), ("joint-offsets", 1e-2), ("joint-offsets", 1e-1),
                                       ("full", 1e-3)])
def test_the_fit_reaches_the_optimum_scipy_finds_with_the_same_unknowns_held(sessions, side, candidate):
    """The damped Gauss-Newton fit stopped converged at the cost scipy's least_squares (trust-region reflective,
    tolerances 1e-15) reaches from the nominal on the same objective (the rows it kept, the Tikhonov term) and the
    same free unknowns, within 1e-6 of it."""
    from scipy.optimize import least_squares
    from tolerance_ros.core.calibration.contact import _stack, fit_contacts
    model, data, nominal = sessions[side]
    which, weight = candidate
    f = fit_contacts(model, data, nominal, which, tikhonov=weight, analysis=False)
    assert f.convergence.converged, f.convergence
    lay, free = f.layout, _free(model, data, f)
    ridge = np.where(free < model.n_params, weight or 0.0, 0.0)
    keep = np.sqrt((~f.rejected).astype(float))

    def residuals(z):
        x = np.zeros(lay.n)
        x[free] = z
        return np.r_[_stack(model, data, x, f.reference, lay, keep)[1], np.sqrt(ridge) * z]
    ref = least_squares(residuals, np.zeros(len(free)), method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15,
                        x_scale=1e-3)
    ours, theirs = float(np.sum(residuals(f.x[free]) ** 2)), float(np.sum(ref.fun ** 2))
    assert abs(ours - theirs) <= 1e-6 * theirs, (ours, theirs)
    assert ours == pytest.approx(f.convergence.cost, rel=1e-9)


@pytest.mark.parametrize("side", list(tc.SESSIONS))
def test_what_contact_cannot_see_on_the_training_sessions_is_held_and_said(sessions, side):
    """The ankle's roll turns the robot about the table's normal (a motion of the rig), its pitch is nearly the
    table's tilt; the fingertips' places along the table are held at their nominal places; the noise is estimated
    from the rows, the rig's misfit first, then what the joint offsets leave."""
    from tolerance_ros.core.calibration.contact import fit_contacts
    model, data, nominal = sessions[side]
    f = fit_contacts(model, data, nominal, "joint-offsets")
    assert f.convergence.converged
    assert f.held_why[f"leg_{side}_6_joint.offset"].startswith("a motion of the rig")
    assert f.held_why[f"leg_{side}_5_joint.offset"].startswith("nearly a motion of the rig")
    assert all(not f.targets_why[f"F{k}.{a}"]["fitted"] for k in (1, 2, 3) for a in "xy")
    assert not f.noise_given and 0.1e-3 < f.noise_robust < f.noise_rig < 0.05
    rig = f.rig
    assert rig.d_std[0] > 0 and np.all(rig.normals_std[0] > 0)      # the session's plane, fitted


@pytest.mark.parametrize("side", list(tc.SESSIONS))
def test_the_elastic_fit_reaches_the_optimum_scipy_finds_with_the_same_unknowns_held(sessions, side):
    """The joint offsets with every joint's compliance (the root link held, as the defaults choose on these sessions):
    the cost with its Tikhonov term on the offsets and the compliances' prior, weighed at the fit's noise, within
    1e-6 of scipy's minimum over the same free unknowns."""
    from scipy.optimize import least_squares
    from tolerance_ros.core.calibration.contact import (DEFLECTIONS, ELASTIC, ELASTIC_TIKHONOV, _largest_loads, _stack,
                                                        fit_contacts, model_for)
    from tolerance_ros.core.calibration.elastic import HELD
    plain, data, nominal = sessions[side]
    model = model_for(plain, ELASTIC, data, HELD)
    f = fit_contacts(model, data, nominal, ELASTIC, tikhonov=ELASTIC_TIKHONOV, deflection=DEFLECTIONS[0],
                     analysis=False)
    assert f.convergence.converged, f.convergence
    lay, free = f.layout, _free(model, data, f)
    weight = np.zeros(lay.n)
    weight[:plain.n_params] = ELASTIC_TIKHONOV
    comp = model.compliance_columns()
    weight[comp] = (f.prior_weight * _largest_loads(model, data.q)[comp] / DEFLECTIONS[0]) ** 2
    keep = np.sqrt((~f.rejected).astype(float))

    def residuals(z):
        x = np.zeros(lay.n)
        x[free] = z
        return np.r_[_stack(model, data, x, f.reference, lay, keep)[1], np.sqrt(weight[free]) * z]
    scale = np.full(lay.n, 1e-3)
    scale[comp] = DEFLECTIONS[0] / _largest_loads(model, data.q)[comp]
    ref = least_squares(residuals, np.zeros(len(free)), method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15,
                        x_scale=scale[free])
    ours, theirs = float(np.sum(residuals(f.x[free]) ** 2)), float(np.sum(ref.fun ** 2))
    assert abs(ours - theirs) <= 1e-6 * theirs, (ours, theirs)
