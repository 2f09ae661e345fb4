"""The contact campaign CSV: read, written, and every bad input named by its line and column."""
import numpy as np
import pytest

from tolerance_ros.core.accuracy.io.contact_csv import is_contact_csv, read_contacts, write_contacts
from tolerance_ros.core.accuracy.io.measurements import MeasurementError

JOINTS = ("j1", "j2")
HEADER = "stamp[s],pose,session,target,contact,joint:j1[deg],joint:j2[rad]"


def write(tmp_path, *lines, name="c.csv"):
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def test_a_campaign_reads_in_si_and_round_trips(tmp_path):
    p = write(tmp_path, "# a comment", HEADER, "0.5,P1,s1,A,plane:table,90,0.25", "1.5,P2,s2,B,point:tip,-45,-1")
    c = read_contacts(p, JOINTS)
    assert is_contact_csv(p) and len(c) == 2
    assert np.allclose(c.joints, [[np.pi / 2, 0.25], [-np.pi / 4, -1.0]])
    assert list(c.contact) == ["plane:table", "point:tip"] and list(c.session) == ["s1", "s2"]
    assert list(c.target) == ["A", "B"] and c.where(1) == "line 4"
    out = write_contacts(tmp_path / "w.csv", c.stamps, c.pose, c.session, c.target, c.contact, c.joints, JOINTS)
    again = read_contacts(out, JOINTS)
    assert np.array_equal(again.joints, c.joints) and list(again.contact) == list(c.contact)


def test_columns_of_joints_outside_the_chain_are_ignored_and_listed(tmp_path):
    p = write(tmp_path, HEADER + ",joint:gripper[m]", "0,P,s,A,plane:t,1,2,0.04")
    c = read_contacts(p, JOINTS)
    assert c.ignored == ["gripper"] and c.joints.shape == (1, 2)


def test_the_readings_of_joints_outside_the_chain_are_kept_in_si(tmp_path):
    """The rest of a standing robot's posture loads its joints: columns outside the chain with an angle or length
    unit are read (SI) beside the chain's; one without a unit is only listed; a bad number there is named."""
    p = write(tmp_path, HEADER + ",joint:knee[deg],joint:gripper[mm],joint:note[x]", "0,P,s,A,plane:t,1,2,90,40,7",
              "1,Q,s,A,plane:t,1,2,-45,20,8")
    c = read_contacts(p, JOINTS)
    assert c.ignored == ["gripper", "knee", "note"] and c.other_names == ("gripper", "knee")
    assert np.allclose(c.others, [[0.04, np.pi / 2], [0.02, -np.pi / 4]])
    assert np.allclose(c.select([1]).others, [[0.02, -np.pi / 4]])
    bad = write(tmp_path, HEADER + ",joint:knee[deg]", "0,P,s,A,plane:t,1,2,x", name="bad.csv")
    with pytest.raises(MeasurementError, match="line 2: joint:knee: not a number"):
        read_contacts(bad, JOINTS)


@pytest.mark.parametrize("lines, words", [
    (["stamp[s],pose,target,contact,joint:j1[deg],joint:j2[rad]"], "needs the column(s) ['session']"),
    (["stamp[s],session,target,contact,joint:j1[deg]"], "no column for joint(s) ['j2']"),
    (["stamp[s],session,target,contact,joint:j1[mm],joint:j2[rad]"], "joint:j1' (revolute) needs an angle unit"),
    (["stamp,session,target,contact,joint:j1[deg],joint:j2[rad]"], "column 'stamp' needs a time unit"),
    (["stamp[s];session;target;contact"], "separated by semicolons"),
    ([HEADER, "0,P,s,A,line:x,1,2"], "line 2: contact: expected plane:ID or point:ID"),
    ([HEADER, "0,P,s,A,plane:t,1,nan"], "line 2: joint:j2: not a number"),
    ([HEADER, "0,P,s,A,plane:t,1,2,3"], "line 2: 8 fields where the header has 7"),
    ([HEADER, "0,P,s,,plane:t,1,2"], "line 2: target: empty"),
    ([HEADER + ",x[mm]"], "unknown column(s) ['x']"),
    ([HEADER], "no contacts"),
])
def test_bad_input_is_named(tmp_path, lines, words):
    with pytest.raises(MeasurementError) as exc:
        read_contacts(write(tmp_path, *lines), JOINTS)
    assert words in str(exc.value)


def test_a_bad_row_is_skipped_and_listed_when_asked(tmp_path):
    p = write(tmp_path, HEADER, "0,P,s,A,plane:t,1,2", "1,P,s,A,plane:t,1,oops", "2,P,s,A,plane:t,3,4")
    c = read_contacts(p, JOINTS, skip_bad=True)
    assert len(c) == 2 and c.skipped[0]["line"] == 3 and "not a number" in c.skipped[0]["reason"]


def test_a_tracker_csv_is_not_a_contact_campaign(tmp_path):
    p = write(tmp_path, "stamp[s],x[mm],y[mm],z[mm],joint:j1[deg],joint:j2[rad]", "0,1,2,3,4,5")
    assert not is_contact_csv(p) and not is_contact_csv(tmp_path / "missing.csv")
