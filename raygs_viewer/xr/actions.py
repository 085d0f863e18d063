"""The controllers, read through one OpenXR action set ("raygs").

OpenXR never names a button: the application declares *actions* and suggests, per
*interaction profile* (a controller family), which of the controller's inputs drive
them; the runtime picks the profile of the controllers in the user's hands, or maps
ours onto theirs. Four actions, each per hand (subaction paths /user/hand/left and
/user/hand/right):

- ``grip_pose``: where the hand holds the controller (its grip pose), located in the
  session's room space each frame; a hand the runtime does not track has no pose.
- ``grab``: the grip (squeeze) button. Holding one grip grabs the world and moves it
  with the hand; holding both grabs it with both hands, and their distance scales it.
  A squeeze *value* counts as held from 0.5 and as let go below 0.4 (hysteresis: a
  squeeze resting near one threshold does not flicker); a click is 0 or 1.
- ``move``: the thumbstick (or the Vive's trackpad). The left stick moves (x right,
  y forward), the right stick's x turns; the simple controller has none.
- ``recentre``: a button that puts the scene back in front of the viewer: A on the
  right Touch controller and X on the left one, A on the Index controllers, the menu
  button on the Vive and simple controllers.

:data:`BINDINGS` is the whole table (:func:`binding_lines` prints it for the docs and
``doctor``); :class:`ControllerActions` suggests it to the runtime, attaches the set
to a session and reads both hands as :class:`~raygs_viewer.xr.controls.HandInput`.
pyopenxr is loaded through :func:`~raygs_viewer.xr.runtime.load_openxr` when the
actions are made, so the table can be read without it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from raygs_viewer.errors import UserError
from raygs_viewer.xr.controls import NO_HAND, HandInput
from raygs_viewer.xr.room import Pose
from raygs_viewer.xr.runtime import error_line, load_openxr

ACTION_SET = "raygs"
#: The subaction paths, left hand first: every action is read per hand, in this order.
HANDS = ("/user/hand/left", "/user/hand/right")
#: Each action's name, its pyopenxr ``xr.ActionType`` member and what a runtime's
#: rebinding screen shows for it.
ACTIONS = {
    "grip_pose": ("POSE_INPUT", "Hand (grip pose)"),
    "grab": ("FLOAT_INPUT", "Grab the world"),
    "move": ("VECTOR2F_INPUT", "Move and turn"),
    "recentre": ("BOOLEAN_INPUT", "Recentre the scene"),
}
#: A squeeze value counts as a held grip from GRAB_PRESS, and as let go below GRAB_RELEASE.
GRAB_PRESS = 0.5
GRAB_RELEASE = 0.4

SIMPLE = "/interaction_profiles/khr/simple_controller"
TOUCH = "/interaction_profiles/oculus/touch_controller"
INDEX = "/interaction_profiles/valve/index_controller"
VIVE = "/interaction_profiles/htc/vive_controller"

#: {interaction profile: {action: the input paths suggested for it}}: the suggested
#: bindings, as the runtime gets them (a profile without an action leaves it unbound:
#: the simple controller has no stick).
BINDINGS: dict[str, dict[str, tuple[str, ...]]] = {
    SIMPLE: {
        "grip_pose": ("/user/hand/left/input/grip/pose", "/user/hand/right/input/grip/pose"),
        "grab": ("/user/hand/left/input/select/click", "/user/hand/right/input/select/click"),
        "recentre": ("/user/hand/left/input/menu/click", "/user/hand/right/input/menu/click"),
    },
    TOUCH: {
        "grip_pose": ("/user/hand/left/input/grip/pose", "/user/hand/right/input/grip/pose"),
        "grab": ("/user/hand/left/input/squeeze/value", "/user/hand/right/input/squeeze/value"),
        "move": ("/user/hand/left/input/thumbstick", "/user/hand/right/input/thumbstick"),
        "recentre": ("/user/hand/left/input/x/click", "/user/hand/right/input/a/click"),
    },
    INDEX: {
        "grip_pose": ("/user/hand/left/input/grip/pose", "/user/hand/right/input/grip/pose"),
        "grab": ("/user/hand/left/input/squeeze/value", "/user/hand/right/input/squeeze/value"),
        "move": ("/user/hand/left/input/thumbstick", "/user/hand/right/input/thumbstick"),
        "recentre": ("/user/hand/left/input/a/click", "/user/hand/right/input/a/click"),
    },
    VIVE: {
        "grip_pose": ("/user/hand/left/input/grip/pose", "/user/hand/right/input/grip/pose"),
        "grab": ("/user/hand/left/input/squeeze/click", "/user/hand/right/input/squeeze/click"),
        "move": ("/user/hand/left/input/trackpad", "/user/hand/right/input/trackpad"),
        "recentre": ("/user/hand/left/input/menu/click", "/user/hand/right/input/menu/click"),
    },
}


def binding_lines(bindings: Mapping[str, Mapping[str, Sequence[str]]] = BINDINGS) -> list[str]:
    """One line per profile and action, e.g. ``valve/index_controller  grab:
    left squeeze/value, right squeeze/value`` (the docs' table and ``doctor``)."""
    lines = []
    for profile, actions in bindings.items():
        short = profile.removeprefix("/interaction_profiles/")
        for action, paths in actions.items():
            inputs = ", ".join(_short_input(path) for path in paths)
            lines.append(f"{short}  {action}: {inputs}")
    return lines


def _short_input(path: str) -> str:
    """"/user/hand/left/input/squeeze/value" -> "left squeeze/value"."""
    hand, _, control = path.removeprefix("/user/hand/").partition("/input/")
    return f"{hand} {control}" if control else path


def grab_held(value: float, *, was_held: bool) -> bool:
    """Whether a grip whose squeeze reads ``value`` (0..1) is held, given whether it was
    held at the last read: pressed from :data:`GRAB_PRESS`, let go below
    :data:`GRAB_RELEASE`."""
    return value >= GRAB_RELEASE if was_held else value >= GRAB_PRESS


class ControllerActions:
    """The action set, its four actions and (after :meth:`attach`) one grip-pose space
    per hand. Made by :meth:`create` before the session (bindings can only be suggested
    before an action set is attached); :meth:`destroy` ends what it made."""

    def __init__(self, xr, instance, action_set, actions: dict):
        self.xr = xr
        self.instance = instance
        self.action_set = action_set
        #: {action name: xr.Action}
        self.actions = actions
        self.hand_paths = tuple(xr.string_to_path(instance, hand) for hand in HANDS)
        #: Each hand's grip-pose space (left, right), made by :meth:`attach`.
        self.grip_spaces: tuple = ()
        #: Whether the last :meth:`read` found the session focused (input flows only then).
        self.focused = False
        self.grab_was_held = [False, False]

    @classmethod
    def create(cls, instance, *, bindings: Mapping[str, Mapping[str, Sequence[str]]] = BINDINGS
               ) -> ControllerActions:
        """The action set and its actions on ``instance`` (an ``xr.Instance``), with
        ``bindings`` suggested profile by profile; a profile or path the runtime refuses is
        a UserError naming the profile (nothing is left behind)."""
        xr = load_openxr()
        try:
            action_set = xr.create_action_set(instance, xr.ActionSetCreateInfo(
                action_set_name=ACTION_SET, localized_action_set_name="raygs-viewer", priority=0))
        except xr.ResultException as exc:
            raise UserError(error_line(exc, xr, "making the controllers' action set")) from None
        made = cls(xr, instance, action_set, {})
        try:
            for name, (kind, label) in ACTIONS.items():
                made.actions[name] = xr.create_action(action_set, xr.ActionCreateInfo(
                    action_name=name, action_type=getattr(xr.ActionType, kind),
                    subaction_paths=list(made.hand_paths), localized_action_name=label))
            for profile, actions in bindings.items():
                made.suggest(profile, actions)
        except BaseException:
            made.destroy()
            raise
        return made

    def suggest(self, profile: str, actions: Mapping[str, Sequence[str]]) -> None:
        """Suggests one interaction profile's bindings ({action: input paths})."""
        xr = self.xr
        try:
            xr.suggest_interaction_profile_bindings(self.instance, xr.InteractionProfileSuggestedBinding(
                interaction_profile=xr.string_to_path(self.instance, profile),
                suggested_bindings=[xr.ActionSuggestedBinding(self.actions[action],
                                                              xr.string_to_path(self.instance, path))
                                    for action, paths in actions.items() for path in paths]))
        except xr.ResultException as exc:
            raise UserError(error_line(exc, xr, f"suggesting the controller bindings of {profile}")) from None

    def attach(self, session) -> None:
        """Makes each hand's grip-pose space and attaches the action set to ``session``
        (once per session; no binding can be suggested after)."""
        xr = self.xr
        try:
            self.grip_spaces = tuple(
                xr.create_action_space(session, xr.ActionSpaceCreateInfo(
                    action=self.actions["grip_pose"], subaction_path=hand, pose_in_action_space=xr.Posef()))
                for hand in self.hand_paths)
            xr.attach_session_action_sets(session, xr.SessionActionSetsAttachInfo(action_sets=[self.action_set]))
        except xr.ResultException as exc:
            raise UserError(error_line(exc, xr, "attaching the controllers to the session")) from None

    def read(self, session, space, time: int) -> tuple[HandInput, HandInput]:
        """Both hands (left, right) now: the actions synced with the set active, each
        hand's grip pose located in ``space`` (the room) at ``time`` (an XrTime, e.g. the
        frame's predicted display time). A session that is not focused gets no input
        (the runtime says so rather than failing): both hands are :data:`NO_HAND`."""
        xr = self.xr
        try:
            xr.sync_actions(session, xr.ActionsSyncInfo(
                active_action_sets=[xr.ActiveActionSet(self.action_set, xr.NULL_PATH)]))
        except (xr.SessionNotFocused, xr.SessionLossPending):
            self.focused = False
            self.grab_was_held = [False, False]
            return NO_HAND, NO_HAND
        self.focused = True
        left, right = (self.read_hand(session, space, time, hand=index) for index in range(len(HANDS)))
        return left, right

    def read_hand(self, session, space, time: int, *, hand: int) -> HandInput:
        """One hand's input (``hand``: 0 left, 1 right) after :meth:`read`'s sync."""
        xr = self.xr
        path = self.hand_paths[hand]

        def get(function, action: str):
            return function(session, xr.ActionStateGetInfo(action=self.actions[action], subaction_path=path))

        grab = get(xr.get_action_state_float, "grab")
        held = bool(grab.is_active) and grab_held(float(grab.current_state), was_held=self.grab_was_held[hand])
        self.grab_was_held[hand] = held
        move = get(xr.get_action_state_vector2f, "move")
        stick = (float(move.current_state.x), float(move.current_state.y)) if move.is_active else (0.0, 0.0)
        recentre = get(xr.get_action_state_boolean, "recentre")
        return HandInput(pose=self.grip_pose(space, time, hand=hand), grip=held, stick=stick,
                         recentre=bool(recentre.is_active and recentre.current_state))

    def grip_pose(self, space, time: int, *, hand: int) -> Pose | None:
        """The hand's grip pose in ``space`` at ``time``, or None when the runtime cannot
        say both where it is and how it is turned (its valid flags) or says it in numbers
        that are no pose."""
        xr = self.xr
        location = xr.locate_space(self.grip_spaces[hand], space, time)
        valid = xr.SpaceLocationFlags.POSITION_VALID_BIT | xr.SpaceLocationFlags.ORIENTATION_VALID_BIT
        if (int(location.location_flags) & int(valid)) != int(valid):
            return None
        q, p = location.pose.orientation, location.pose.position
        try:
            return Pose(np.array([q.x, q.y, q.z, q.w], dtype=np.float64), np.array([p.x, p.y, p.z], dtype=np.float64))
        except ValueError:  # flagged valid, yet a zero or non-finite pose: a runtime's slip, read as untracked
            return None

    def destroy(self) -> None:
        """Destroys the grip spaces and the action set (with its actions); a second call
        does nothing."""
        xr = self.xr
        spaces, self.grip_spaces = self.grip_spaces, ()
        for space in spaces:
            xr.destroy_space(space)
        action_set, self.action_set = self.action_set, None
        if action_set is not None:
            xr.destroy_action_set(action_set)
        self.actions = {}
