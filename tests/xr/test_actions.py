"""The controllers' action set against a real runtime (Monado, headless: no graphics and
no frame loop, only the session's states and the input), and its bindings table.

The known answers come from Monado's simulated devices builder
(src/xrt/targets/common/target_builder_simulated.c): with no ``SIMULATED_LEFT`` /
``SIMULATED_RIGHT`` the system has a headset and no controllers, so both hands are
untracked and unpressed; with both set to ``wmr`` each hand holds a simulated WMR
controller resting at (∓0.2, 1.3, -0.5) m in the tracking origin (the STAGE space),
unrotated, with no button pressed. The runtime maps it onto the simple controller
profile, the only one of ours its bindings name. The script's room is the STAGE space
moved and turned (ROOM_AXIS, ROOM_ANGLE, ROOM_OFFSET), so the hands' poses in it have
every coordinate of position and orientation in play.
"""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest
import xr_kit

from raygs_viewer.xr.actions import (
    BINDINGS,
    GRAB_PRESS,
    GRAB_RELEASE,
    HANDS,
    binding_lines,
    grab_held,
)

PROFILES = {"/interaction_profiles/khr/simple_controller", "/interaction_profiles/oculus/touch_controller",
            "/interaction_profiles/valve/index_controller", "/interaction_profiles/htc/vive_controller"}

#: The room in the STAGE space: turned by ROOM_ANGLE about ROOM_AXIS, its origin at ROOM_OFFSET.
ROOM_AXIS = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
ROOM_ANGLE = 0.7
ROOM_OFFSET = np.array([0.3, -0.1, 0.25])
ROOM_QUATERNION = [*(ROOM_AXIS * np.sin(ROOM_ANGLE / 2)), np.cos(ROOM_ANGLE / 2)]  # (x, y, z, w)

# A headless session (XR_MND_headless) has no compositor: Monado's xrWaitFrame returns no
# display time and xrBeginFrame refuses, so the script takes "now" as the time to locate
# at, through XR_KHR_convert_timespec_time. It prints one JSON line per event of note.
SCRIPT = r"""
import ctypes, json, sys, time
import xr
from xr.platform.linux import convert_timespec_time_to_time_khr, timespec
from raygs_viewer.errors import UserError
from raygs_viewer.xr.actions import ControllerActions

def say(**fields):
    print(json.dumps(fields), flush=True)

offered = {p.extension_name.decode() for p in xr.enumerate_instance_extension_properties()}
wanted = [xr.MND_HEADLESS_EXTENSION_NAME, xr.KHR_CONVERT_TIMESPEC_TIME_EXTENSION_NAME]
if not set(wanted) <= offered:
    say(kind="missing", extensions=sorted(set(wanted) - offered))
    sys.exit(0)
instance = xr.create_instance(xr.InstanceCreateInfo(enabled_extension_names=wanted))
system = xr.get_system(instance, xr.SystemGetInfo(form_factor=xr.FormFactor.HEAD_MOUNTED_DISPLAY))

# The control: a path the simple controller does not have is refused.
try:
    ControllerActions.create(instance, bindings={
        "/interaction_profiles/khr/simple_controller": {"grab": ["/user/hand/left/input/nonexistent/click"]}})
    say(kind="wrong path", refused=False)
except UserError as exc:
    say(kind="wrong path", refused=True, message=str(exc))

actions = ControllerActions.create(instance)  # every profile of BINDINGS: raises if one is refused
session = xr.create_session(instance, xr.SessionCreateInfo(system_id=system))
actions.attach(session)
q, t = json.loads(sys.argv[1])
room = xr.create_reference_space(session, xr.ReferenceSpaceCreateInfo(
    reference_space_type=xr.ReferenceSpaceType.STAGE,
    pose_in_reference_space=xr.Posef(xr.Quaternionf(*q), xr.Vector3f(*t))))

def now():
    ns = time.monotonic_ns()
    return convert_timespec_time_to_time_khr(instance, timespec(ns // 10**9, ns % 10**9))

def hand(h):
    pose = None if h.pose is None else [list(h.pose.position), list(h.pose.orientation)]
    return dict(pose=pose, grip=h.grip, stick=list(h.stick), recentre=h.recentre)

def read(stage):
    hands = actions.read(session, room, now())
    say(kind="read", stage=stage, focused=actions.focused, hands=[hand(h) for h in hands])

read("before begin")
states, reads, deadline = [], 0, time.monotonic() + 20
while time.monotonic() < deadline:
    try:
        event = xr.poll_event(instance)
    except xr.EventUnavailable:
        if states and states[-1] == "FOCUSED" and reads < 3:
            read("focused")
            reads += 1
            if reads == 3:
                xr.request_exit_session(session)
        time.sleep(0.005)
        continue
    if xr.StructureType(event.type) != xr.StructureType.EVENT_DATA_SESSION_STATE_CHANGED:
        continue
    changed = ctypes.cast(ctypes.byref(event), ctypes.POINTER(xr.EventDataSessionStateChanged)).contents
    state = xr.SessionState(changed.state)
    states.append(state.name)
    if state == xr.SessionState.READY:
        xr.begin_session(session, xr.SessionBeginInfo(
            primary_view_configuration_type=xr.ViewConfigurationType.PRIMARY_STEREO))
    elif state == xr.SessionState.STOPPING:
        read("stopping")
        xr.end_session(session)
    elif state == xr.SessionState.EXITING:
        break
say(kind="states", states=states)
xr.destroy_space(room)
actions.destroy()
actions.destroy()  # a second call does nothing
xr.destroy_session(session)
xr.destroy_instance(instance)
say(kind="done")
"""

NOBODY = {"pose": None, "grip": False, "stick": [0.0, 0.0], "recentre": False}


def run_session(**extra: str) -> list[dict]:
    """The script's JSON lines, run against Monado with ``extra`` in its environment
    (once per environment: two tests read the same run)."""
    return list(session_lines(tuple(sorted(extra.items()))))


@functools.cache
def session_lines(extra: tuple[tuple[str, str], ...]) -> tuple[dict, ...]:
    reason = xr_kit.skip_reason()
    if reason is not None:
        pytest.skip(reason)
    room = json.dumps([[float(v) for v in ROOM_QUATERNION], [float(v) for v in ROOM_OFFSET]])
    done = xr_kit.run_child(["-c", SCRIPT, room], xr_kit.runtime_env(**dict(extra)))
    assert done.returncode == 0, done.stderr[-3000:]
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    if lines and lines[0]["kind"] == "missing":
        pytest.skip(f"this Monado does not offer {lines[0]['extensions']}")
    assert lines[-1] == {"kind": "done"}, done.stdout
    return tuple(lines)


def of_kind(lines: list[dict], kind: str) -> list[dict]:
    return [line for line in lines if line["kind"] == kind]


def test_a_headset_without_controllers_reads_two_untracked_idle_hands():
    lines = run_session()
    states = of_kind(lines, "states")[0]["states"]
    assert states == ["IDLE", "READY", "SYNCHRONIZED", "VISIBLE", "FOCUSED",
                      "VISIBLE", "SYNCHRONIZED", "STOPPING", "IDLE", "EXITING"]
    reads = of_kind(lines, "read")
    assert [r["stage"] for r in reads] == ["before begin", "focused", "focused", "focused", "stopping"]
    assert [r["focused"] for r in reads] == [False, True, True, True, False]
    for r in reads:
        assert r["hands"] == [NOBODY, NOBODY], r


def test_the_runtime_refuses_a_path_the_profile_lacks():
    """The control of the acceptance above: the runtime does check each suggested path, so
    a wrong one in BINDINGS would have failed the session script."""
    wrong = of_kind(run_session(), "wrong path")[0]
    assert wrong["refused"], wrong
    assert "/interaction_profiles/khr/simple_controller" in wrong["message"]


def room_rotation() -> np.ndarray:
    """(3, 3) the room's axes in the STAGE space: Rodrigues' formula for ROOM_AXIS, ROOM_ANGLE."""
    x, y, z = ROOM_AXIS
    cross = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + np.sin(ROOM_ANGLE) * cross + (1 - np.cos(ROOM_ANGLE)) * cross @ cross


def test_simulated_controllers_are_tracked_where_monado_holds_them():
    reads = of_kind(run_session(SIMULATED_LEFT="wmr", SIMULATED_RIGHT="wmr"), "read")
    focused = [r for r in reads if r["stage"] == "focused"]
    assert len(focused) == 3 and all(r["focused"] for r in focused)
    # An unrotated controller at p in the STAGE space is, in the room, at Rᵀ (p - offset),
    # turned by the room's inverse rotation: the conjugate quaternion.
    turned_back = [-ROOM_QUATERNION[0], -ROOM_QUATERNION[1], -ROOM_QUATERNION[2], ROOM_QUATERNION[3]]
    for r in focused:
        for hand, x in zip(r["hands"], (-0.2, 0.2)):
            position, orientation = hand["pose"]
            expected = room_rotation().T @ (np.array([x, 1.3, -0.5]) - ROOM_OFFSET)
            assert position == pytest.approx(expected, abs=1e-5)
            sign = 1.0 if orientation[3] >= 0 else -1.0  # q and -q are one rotation
            assert [sign * v for v in orientation] == pytest.approx(turned_back, abs=1e-5)
            assert (hand["grip"], hand["stick"], hand["recentre"]) == (False, [0.0, 0.0], False)
    # Not focused, the tracked hands still read as nobody's: no input reaches an unfocused session.
    assert [r["hands"] for r in reads if not r["focused"]] == [[NOBODY, NOBODY]] * 2


def test_every_profile_binds_the_grip_pose_and_grab_on_both_hands():
    assert set(BINDINGS) == PROFILES
    for profile, actions in BINDINGS.items():
        for action in ("grip_pose", "grab"):
            hands = sorted(path.split("/")[3] for path in actions[action])
            assert hands == ["left", "right"], (profile, action)
        # The simple controller alone has no stick.
        assert ("move" in actions) == (profile != "/interaction_profiles/khr/simple_controller"), profile
        assert "recentre" in actions, profile


def test_every_binding_is_an_input_of_a_hand_and_every_action_exists():
    for profile, actions in BINDINGS.items():
        assert set(actions) <= {"grip_pose", "grab", "move", "recentre"}, profile
        for paths in actions.values():
            for path in paths:
                assert path.startswith("/user/hand/"), path
                assert path.split("/")[3] in ("left", "right") and path.split("/")[4] == "input", path
    assert HANDS == ("/user/hand/left", "/user/hand/right")


def test_binding_lines_give_one_line_per_profile_and_action():
    lines = binding_lines()
    assert len(lines) == 3 + 4 + 4 + 4
    assert "oculus/touch_controller  recentre: left x/click, right a/click" in lines
    assert "htc/vive_controller  move: left trackpad, right trackpad" in lines
    assert not any(line.startswith("khr/simple_controller  move") for line in lines)


@pytest.mark.parametrize(("value", "was_held", "held"), [
    (0.0, False, False), (0.49, False, False), (0.5, False, True), (1.0, False, True),
    (0.45, True, True), (0.4, True, True), (0.39, True, False), (0.0, True, False),
])
def test_a_squeeze_is_held_from_one_half_and_let_go_below_four_tenths(value, was_held, held):
    assert (GRAB_PRESS, GRAB_RELEASE) == (0.5, 0.4)
    assert grab_held(value, was_held=was_held) is held
