"""Contact from the events alone: touching or not, and the phase, per frame, causally, in O(1) state.

Why a state machine and not a threshold on the event rate: a held object makes almost no events
(the membrane is still), so a quiet frame is either rest or a steady hold. What tells them apart
is the history: pressing darkens the membrane (a burst of OFF events), releasing brightens it back
(a burst of ON events). So:

- rest -> touching (phase grasping) when a frame's OFF count rises above the background by
  `onset_sigma` Poisson σ and by `min_events`, unless the frame is ON-dominated (a release darkens
  the rim a little as it lets go, in the same frames as its ON burst: no press);
- grasping -> holding once the OFF count above the background falls under `settled_share` of the
  peak's (a later OFF burst, a re-grasp, goes back to grasping);
- touching -> releasing on an ON-dominated burst (`dominance` times more ON than OFF events; a
  sensor whose training releases fail that bar gets its own, `dominance_for`);
- releasing -> rest: with a force model (`end_by_force`), once its estimate has stayed under
  `release_force_n` for `low_frames` frames after such a burst (a re-grasp loosens the grip and
  tightens it some frames later, so the first low frame is not yet the end), or once the OFF
  activity since the first such burst has been at the background's level for about `quiet_frames` frames
  while the estimate is under `quiet_force_share` of its peak in the contact, or the release bursts
  brightened the membrane by `quiet_release_share` of the press's peak OFF count (a model may read a
  little force after a release for a while, or not fall at all; a steady hold is as quiet as rest,
  so the quiet alone would end it, and an ON flicker while the object settles looks like a
  release); alone, when the ON events of that run of bursts reach `release_share` of the OFF events
  since the onset. The event counts alone cannot tell a full release from a partial one or a
  re-grasp (their ranges overlap on simulated sessions), the force estimate can. The figures that
  chose these rules are in docs/journal.md.

A slip is judged on the events of the contact's footprint (the cells the press darkened, and their
neighbours) above that footprint's own background, when the caller passes each frame's counts: a
slip happens where the object touches, while the background noise is spread over the whole frame, so
on a camera with a busy background (hundreds of events a frame) or a high ON threshold a slip's few
ON events stand out of the footprint's few cells where they drown in the frame's sum. They are
counted above the hold's own activity there (a running mean over the contact's hold frames), where
that exceeds a tenth of the bars: a trembling object or a creeping membrane keeps making events of
both polarities through a hold, which passed the bars frame after frame as one long slip. The slip bars
follow the stream's own presses (`follow_gain`): a model carries the bars of the sensor it was trained
on, and another camera or membrane makes slips of a few times more or fewer events, as it makes
presses. The phases use
the whole frame's totals: releases judged on the footprint end holds at their flickers (the release
rules were chosen on the totals; docs/journal.md).

A frame whose events cover most of the view (`FLASH_SHARE` of its cells, where it has `FLASH_CELLS`
or more) begins no contact: an LED blink or a lamp changes the light over the whole membrane, a press
only where the object is (the LED sync's own test of coverage). Nor does a frame in which the view
moves (`_scene_moves`: both polarities in the same cells, over `SCENE_SHARE` of them, in the frame
or one in it and the other within `scene_frames` before: an LED that lights part of the view and
goes dark frames later), or the `scene_frames` frames after it: a camera on a robot arm sees the
membrane window's edge and the scene slide by, a gripper's motor shakes the membrane before a
touch, and a press makes one polarity in a cell at a time. Where the detector has no frames
(`detect` given sums alone) or frames pooled to a few cells, only the warm-up passes over a blink,
and nothing over a move.

The background (mean OFF and ON counts per frame) starts as the median of a stream's first
`warmup_frames` frames, in which no contact begins: a camera's background can be ten times another's,
and one learnt only from rest frames never recovers from a first contact begun against a wrong one
(every later frame then looks like a burst); the median passes over an LED blink in those frames.
From there it is a running mean over rest frames with a time constant of `background_frames`, so
slow illumination changes and hot pixels move it. The OFF sum since the onset leaks with
`memory_frames`, so a contact that never ends keeps it bounded.
"""

import collections
import math
from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np

NONE, GRASPING, HOLDING, RELEASING = "none", "grasping", "holding", "releasing"


@dataclass(frozen=True)
class ContactConfig:
    onset_sigma: float = 6.0  # OFF count above the background mean by this many Poisson σ ...
    min_events: float = 20.0  # ... and by at least this many events (pooled crop of the frame)
    settled_share: float = 0.25  # grasping ends when OFF falls under this share of its peak
    release_share: float = 0.04  # without a force model: ON of a release run / OFF since the onset that ends a contact
    release_force_n: float = 0.1  # with a force model: after a release burst, a contact ends when its estimate falls below this
    low_frames: int = 20  # ... for this many frames in a row (a re-grasp loosens the grip and tightens it again 6-18 frames later)
    quiet_frames: int = 20  # ... or when the OFF activity since the first release burst (running mean over about this many frames) ...
    quiet_sigma: float = 3.0  # ... is within this many standard errors of the background (the membrane is at rest)
    quiet_force_share: float = 0.5  # ... while the estimate is under this share of its peak in the contact
    quiet_release_share: float = 0.3  # ... or after release bursts whose ON events reach this share of the press's peak OFF
    dominance: float = 2.0  # a release burst has this many times more ON than OFF events
    background_frames: float = 100.0  # time constant of the background's running mean (frames)
    memory_frames: float = 3000.0  # time constant of the sums since the onset (frames): bounded state
    background_off: float = 5.0  # starting background, events per frame (until the first frames replace it)
    background_on: float = 10.0
    warmup_frames: int = 10  # the first frames of a stream set the background (their median); no contact begins in them (0: none)
    lead_frames: int = 2  # the force model reads this many frames before the onset it is started at (training keeps as many)
    press_frames: int = 10  # press_polarity "either": the polarity of a contact's press is the one with more events above
    # the background over this many frames from its onset (a bright object's press can begin with the dark rim about it)
    scene_frames: int = 3  # after a frame of rest in which the view moved (`_scene_moves`), no contact begins for this many frames
    tail_frames: int = 3  # press_polarity "either": a release's polarity begins no contact until it has been under the onset
    # bar this many frames in a row (`tail`: a release burst dips for a frame, or the quiet rule ends a contact just before it)
    await_frames: int = 100  # ... nor, after the quiet rule ended a contact whose release looks partial, in its next burst
    # within this many frames (`_awaits_release`; 0: none): the rest of that release, not an object of the other kind
    press_polarity: str = "off"  # the polarity most of a press's events have ("on": pressing brightens; "either": read at
    # each onset, where a sensor sees objects of both kinds; `press_polarity`)

    def to_dict(self) -> dict:
        return asdict(self)


# The settings above and SlipConfig's were chosen on 10 ms frames. A stream framed at another window
# keeps their durations and event rates (`at_window`): counts of frames scale with 1 / window, counts
# of events in one frame with the window. Not scaled: the frames in which a press's and a release's
# peaks are looked for (PRESS_FRAMES, RELEASE_FRAMES), which are long beside a press at any window
# from a few ms to 20 ms.
REFERENCE_WINDOW_US = 10_000
FRAME_SETTINGS = {"ContactConfig": ("low_frames", "quiet_frames", "background_frames", "memory_frames", "warmup_frames",
                                    "lead_frames", "press_frames", "scene_frames", "tail_frames", "await_frames"),
                  "SlipConfig": ("hold_frames", "settle_frames", "level_frames")}
EVENT_SETTINGS = {"ContactConfig": ("min_events", "background_off", "background_on"), "SlipConfig": ()}


def frames_at(frames: float, window_us: int | None) -> int:
    """A count of 10 ms frames as the same duration in frames of `window_us` (at least 1; unchanged where unknown)."""
    return max(1, round(frames * REFERENCE_WINDOW_US / window_us)) if window_us else int(frames)


def at_window(config, window_us: int | None):
    """`config` (a ContactConfig or SlipConfig chosen on 10 ms frames) for frames of `window_us`: the
    same durations and event rates. Unchanged where the window is unknown. A SlipConfig's bars set
    from a stream's presses (`slip_for`) are counts of that stream's frames already: only the default
    bars, where there were no presses, are scaled."""
    if not window_us or window_us == REFERENCE_WINDOW_US:
        return config
    ratio = window_us / REFERENCE_WINDOW_US
    kind = type(config).__name__
    frames = {name: frames_at(getattr(config, name), window_us) for name in FRAME_SETTINGS[kind]}
    scaled = EVENT_SETTINGS[kind] + (("min_events",) if kind == "SlipConfig" and config.press_off is None else ())
    events = {name: round(getattr(config, name) * ratio, 3) for name in scaled}
    return replace(config, **{name: type(getattr(config, name))(value) for name, value in {**frames, **events}.items()})


POLARITIES = ("off", "on", "either")


def oriented_sums(polarity: str, off, on) -> tuple:
    """A frame's (or frames') OFF and ON sums as the rules here read them, a press's polarity first:
    they are written for a membrane that darkens where pressed (a dark object: OFF) and brightens back
    on release; where pressing brightens it (a bright object, a membrane lit from behind: `polarity`
    "on") the channels are read swapped. The force model reads the frames as given."""
    return (on, off) if polarity == "on" else (off, on)


def polarity_names(polarity: str) -> tuple:
    """How a message names the polarity a press makes and the one a release makes."""
    return {"on": ("ON", "OFF"), "either": ("press-polarity", "release-polarity")}.get(polarity, ("OFF", "ON"))


MAX_FRAMES = 10**8  # a count of frames no stream reaches (11 days of 10 ms frames): past it a setting is damage, not a choice
MAY_BE_ZERO = ("lead_frames", "warmup_frames", "follow_presses", "await_frames")  # counts of frames or presses that may be 0


def checked(config):
    """A ContactConfig or SlipConfig read from a file, its whole-number settings as int; ValueError names
    a setting that no training writes: not a finite number >= 0 (the training peaks and the ON bar may
    be unknown), or a count of frames not whole, under 1 (the lead, the warm-up and the presses followed
    may be 0) or past MAX_FRAMES. Such a value divided by zero, or ran without a word, deep in a stream."""
    counts = set(FRAME_SETTINGS[type(config).__name__]) | {"follow_presses"}
    whole = {}
    for setting in fields(config):
        value = getattr(config, setting.name)
        if value is None and setting.default is None:
            continue
        if setting.name == "press_polarity":
            if value not in POLARITIES:
                raise ValueError(f"press_polarity={value!r} is not one of {', '.join(POLARITIES)}")
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
            raise ValueError(f"{setting.name}={value!r} is not a finite number >= 0")
        lowest = 0 if setting.name in MAY_BE_ZERO else 1
        if setting.name in counts and not lowest <= value <= MAX_FRAMES:
            raise ValueError(f"{setting.name}={value!r} is outside {lowest}..{MAX_FRAMES}")
        if setting.type is int:
            if value != int(value):
                raise ValueError(f"{setting.name}={value!r} is not a whole number")
            whole[setting.name] = int(value)
    return replace(config, **whole)


FOOTPRINT_SHARE = 0.2  # a footprint cell: its OFF events above the background over the presses reach this share of the largest


@dataclass
class Footprint:
    """Where the current contact pressed, over the frame's cells (bounded by the frame's size): the
    background per cell (running mean of rest frames, as the detector's totals), the OFF events above
    it over the contact's presses, and the cells of the footprint."""

    background: np.ndarray | None = None  # (2, H, W) events per frame at rest, its polarities as the state reads them
    rest_frames: int = 0  # rest frames averaged so far (a plain mean until there are background_frames)
    pressed: np.ndarray | None = None  # (H, W) OFF events above the background in the contact's pressing frames
    weights: np.ndarray | None = None  # the footprint's cells as 0/1 over the flattened frame (None before a press)
    expected: tuple = (0.0, 0.0)  # OFF and ON background over the cells (the background is still in a contact), as read

    def turn(self):
        """The background's polarities swapped (`ContactState.turn`); the footprint is a contact's own."""
        if self.background is not None:
            self.background = self.background[::-1].copy()
        self.expected = self.expected[::-1]

    @property
    def cells(self) -> np.ndarray | None:
        """(H, W) bool: the footprint's cells."""
        return None if self.weights is None else self.weights.reshape(self.background.shape[1:]) > 0

    def sums(self, frame: np.ndarray) -> tuple | None:
        """(OFF, ON, OFF background, ON background) over the footprint's cells of one (2, H, W) frame."""
        if self.weights is None or frame.shape != self.background.shape:
            return None
        inside = np.asarray(frame, dtype=np.float32).reshape(2, -1) @ self.weights
        return float(inside[0]), float(inside[1]), *self.expected

    def rest(self, config: "ContactConfig", frame: np.ndarray):
        """A frame of rest: the background per cell follows it (float32: a frame of unpooled cells costs
        tens of microseconds; a one-frame flicker moves a cell by a hundredth of it and fades)."""
        if self.background is None or self.background.shape != frame.shape:
            self.background, self.rest_frames = np.array(frame, dtype=np.float32), 1
            return
        self.rest_frames += 1
        rate = max(1.0 / self.rest_frames, 1.0 / config.background_frames)
        self.background *= np.float32(1.0 - rate)
        self.background += np.float32(rate) * frame

    def press(self, config: "ContactConfig", frame: np.ndarray, onset: bool):
        """A pressing frame: its OFF events above the background mark the footprint (a new contact starts
        a new one; the sum leaks as the detector's do, so a contact that never ends keeps it bounded)."""
        if self.background is None or frame.shape != self.background.shape:
            return
        darker = np.maximum(frame[0] - self.background[0], 0.0, dtype=np.float32)
        keep = np.float32(np.exp(-1.0 / config.memory_frames))
        self.pressed = darker if onset or self.pressed is None else self.pressed * keep + darker
        top = float(self.pressed.max())
        self.weights = _grown(self.pressed >= FOOTPRINT_SHARE * top).ravel().astype(np.float32) if top > 0 else None
        if self.weights is not None:
            self.expected = tuple(float(v) for v in self.background.reshape(2, -1) @ self.weights)


def _grown(cells: np.ndarray) -> np.ndarray:
    """The cells and their eight neighbours (a slip carries the patch's edge past the pressed cells)."""
    rows = cells.copy()
    rows[1:] |= cells[:-1]
    rows[:-1] |= cells[1:]
    out = rows.copy()
    out[:, 1:] |= rows[:, :-1]
    out[:, :-1] |= rows[:, 1:]
    return out


@dataclass
class ContactState:
    """Everything the detector keeps between frames: a handful of numbers, and the footprint's cells."""

    mean_off: float
    mean_on: float
    phase: str = NONE
    off_since: float = 0.0  # OFF events since the onset (leaky)
    peak_off: float = 0.0
    on_run: float = 0.0  # ON events of the current ON-dominated run (a release in progress)
    released: bool = False  # an ON-dominated burst since the last OFF burst: the contact may be over
    held: int = 0  # frames since the phase was last grasping (a press: the object may still be settling)
    held_before: int = 0  # `held` before the last frame
    press_after: int = 0  # `held` when the current press began (0 at an onset): a press of a settled hold may be a slip
    quiet: float = 0.0  # running mean of OFF events since the first release burst after the last press
    since_release: int = 0  # frames since the first release burst after the last press
    released_on: float = 0.0  # ON events above the background in the release bursts since the last press
    peak_force: float = 0.0  # the force model's largest estimate in this contact (set by its caller)
    low: int = 0  # frames in a row the force estimate has been under release_force_n (since the burst; "either": `_unloaded`)
    onsets: int = 0  # contacts begun so far (a new one resets the force model's state)
    slipping: bool = False
    slip_quiet: int = 0  # frames since the last evidence of a slip
    last_excess: tuple = (0.0, 0.0)  # the previous frame's OFF and ON events above their background
    hold_level: tuple = (0.0, 0.0)  # OFF and ON events above their background per frame of this contact's holds (`slip_step`)
    warmup: list | None = field(default_factory=list)  # (OFF, ON) of the stream's first frames; None once they set the background
    footprint: Footprint = field(default_factory=Footprint)
    local: tuple | None = None  # this frame's `Footprint.sums` inside a contact, for `slip_step` (None: the totals)
    gain: "Gain" = field(default_factory=lambda: Gain())  # the stream's own presses, for the slip bars
    polarity: str = "off"  # how the numbers above are read: "on", every OFF / ON pair swapped (`oriented_sums`)
    contact_open: bool = False  # a contact has begun since the state last read a rest frame ("either": its release is the tail)
    tail: str | None = None  # the polarity of the last release while its burst lasts: no press of that polarity begins in it
    tail_quiet: int = 0  # frames in a row the tail's polarity has not risen (`tail_frames`)
    tail_wait: int = 0  # frames left in which the rest of the last contact's release is awaited as its tail (`await_frames`)
    pressed_sum: float = 0.0  # OFF events above the background in the contact's pressing frames (leaky), for `_awaits_release`
    early: "Early | None" = None  # the current contact's first press_frames frames (press_polarity "either")
    frames: int = 0  # frames stepped so far
    silent: int = 0  # frames in a row without an event (`SILENT_FRAMES`)
    scene_at: int = -(1 << 40)  # the frame in which the view last moved between contacts (`_scene_moves`)
    lit: np.ndarray | None = None  # (2, H, W): the frame in which each cell last fired above its rest, per polarity as framed

    @classmethod
    def start(cls, config: ContactConfig) -> "ContactState":
        return cls(mean_off=config.background_off, mean_on=config.background_on, warmup=[] if config.warmup_frames > 0 else None,
                   polarity="on" if config.press_polarity == "on" else "off")

    def turn(self, polarity: str):
        """Read every OFF / ON pair kept here as `polarity` reads them (swapped where it differs from now)."""
        if polarity == self.polarity:
            return
        self.polarity = polarity
        self.mean_off, self.mean_on = self.mean_on, self.mean_off
        self.last_excess, self.hold_level = self.last_excess[::-1], self.hold_level[::-1]
        self.footprint.turn()


def step(config: ContactConfig, state: ContactState, off: float, on: float, by_force: bool = False,
         frame: np.ndarray | None = None) -> str:
    """Advance one frame of `off` and `on` event counts; returns the frame's phase (none = not touching).

    `by_force`: a force model decides the end of a contact (`end_by_force`), not `release_share`.
    `frame`: the frame's (2, H, W) counts, for the footprint on which `slip_step` judges a slip in this
    frame; without it, slips are judged on the totals."""
    state.frames += 1
    state.silent = state.silent + 1 if off + on == 0 else 0
    if state.phase == NONE and state.warmup is None and state.silent > SILENT_FRAMES and state.mean_off + state.mean_on >= SILENT_EVENTS:
        return NONE  # the camera has sent nothing for a while (a gap in a recording, a dropped transfer): no rest to learn from
    if state.phase == NONE and state.warmup is None and frame is not None and _may_begin(config, state, frame, off, on):
        if _flash(state, frame, off, on):
            return NONE  # the light changed over the whole view (an LED, a lamp): no press, and no rest to learn from
        if _scene_moves(config, state, frame):
            return NONE  # the view moved (a camera on an arm, a gripper's motor): no press, and no rest to learn from
    either = config.press_polarity == "either"
    if either:
        _choose_polarity(config, state, off, on)
        _follow_press(config, state, off, on)
    raw = (off, on)
    off, on = oriented_sums(state.polarity, off, on)
    frame = frame[::-1] if frame is not None and state.polarity == "on" else frame
    touching, before = state.phase != NONE, state.onsets
    phase = _step(config, state, off, on, by_force)
    # the footprint as it stood before this frame: a contact's onset frame has none yet
    state.local = state.footprint.sums(frame) if frame is not None and touching else None
    if either and state.onsets != before:
        state.early = Early()
        state.early.add(state, *raw)
    if frame is not None:
        if phase == NONE:
            state.footprint.rest(config, frame)
        elif phase == GRASPING:
            state.footprint.press(config, frame, onset=state.onsets != before)
    return phase


SILENT_EVENTS = 10.0  # rest frames without one event where the background expects this many (Poisson: e^-10 each) ...
SILENT_FRAMES = 3  # ... after this many in a row are a camera that sent nothing. Learnt from, a recording's gap of hours
# takes the background to zero, from which it climbs back by 3σ a frame, and the next contacts end early and split on ON
# events read as release bursts. A camera that sends its events in bursts leaves a frame or two empty between them: learnt from


FLASH_SHARE = 0.8  # a burst over this share of the frame's cells is the light changing, not a press (a crop about a large
# contact can hold half its cells inside it) ...
FLASH_CELLS = 64  # ... on frames of at least this many cells: pooled to a few (`crop --pool all`: one), a press covers them all


SCENE_SHARE = 0.02  # a frame whose cells fire both polarities above their rest background over this share of them ...
SCENE_CELLS = 8  # ... and at least this many is the view moving (a press: at most 0.6% of the cells, on five simulated physics)
SCENE_SIGMA = 3.0  # a cell fires when its count passes its rest background by one event and this many Poisson σ


def _may_begin(config: ContactConfig, state: ContactState, frame: np.ndarray, off: float, on: float) -> bool:
    """Whether a contact could begin in this frame of rest (a polarity's total above its background),
    on a frame of FLASH_CELLS cells or more: only then are its cells looked at (`_flash`,
    `_scene_moves`), so a busy camera's rest frames cost no pass over them. Frames pooled to a few
    cells are not judged: a press covers them all."""
    if np.size(frame) // 2 < FLASH_CELLS:
        return False
    means = oriented_sums(state.polarity, state.mean_off, state.mean_on)  # as framed
    return _above(config, off, means[0]) or _above(config, on, means[1])


def _scene_moves(config: ContactConfig, state: ContactState, frame: np.ndarray) -> bool:
    """Whether the view moves in this frame of rest, where a contact could begin: a camera on a robot
    arm sees the edge of the membrane's window, and the scene through a translucent membrane, slide
    by; a gripper's motor shakes the membrane before a touch. Edges moving make both polarities in the
    same cells over much of the view; a press darkens (or brightens) the object's patch, one polarity
    in a cell at a time. For `scene_frames` frames after such a frame the view is taken as still
    moving (a move's frames pass the bar unevenly). A contact under way is not judged: an arm may
    carry what the gripper holds."""
    background = state.footprint.background
    if background is None or background.shape != np.shape(frame):
        return False
    rest = background[::-1] if state.polarity == "on" else background  # as framed
    # a cell fires above its rest by one event and SCENE_SIGMA Poisson σ: cells of about one event a
    # frame at rest (pooled, busy, or long frames) pass a bar of one event by chance in both polarities
    bar = rest + 1.0 + SCENE_SIGMA * np.sqrt(rest)
    fired = np.asarray(frame) > bar
    if state.lit is None or state.lit.shape != fired.shape:
        state.lit = np.full(fired.shape, -(1 << 40), dtype=np.int64)  # int64: a stream of years of frames does not wrap it
    # a light switched on and off again within a few frames (an LED blink lighting part of the view,
    # one polarity a frame) fires both in the same cells too, in frames of their own
    recent = state.frames - state.lit <= config.scene_frames
    both = int(np.count_nonzero((fired[0] & (fired[1] | recent[1])) | (fired[1] & recent[0])))
    state.lit[fired] = state.frames
    if both >= max(SCENE_SHARE * (np.size(frame) // 2), SCENE_CELLS):
        state.scene_at = state.frames
    return state.frames - state.scene_at <= config.scene_frames


def _choose_polarity(config: ContactConfig, state: ContactState, off: float, on: float):
    """For a sensor that sees objects of both kinds (dark ones press OFF, bright ones ON): between
    contacts the state reads OFF as a press; a frame whose ON events rise above their background more
    than its OFF events do, as an onset's must, turns it to read ON as the press for that contact. The
    burst of the release that just ended a contact begins none (`tail`, `_follow_tail`)."""
    if state.phase != NONE:
        return
    if state.contact_open:  # the contact just ended, read as it pressed: its release's polarity is the tail
        state.tail, state.contact_open, state.tail_quiet = ("off" if state.polarity == "on" else "on"), False, 0
    state.turn("off")
    if state.warmup is not None:
        return
    rises = {"off": _onset(config, off, on, state.mean_off, state.mean_on), "on": _onset(config, on, off, state.mean_on, state.mean_off)}
    _follow_tail(config, state, rises)
    if state.tail is not None:
        rises[state.tail] = False
    if rises["on"] and (not rises["off"] or on - state.mean_on > off - state.mean_off):
        state.turn("on")


def _follow_tail(config: ContactConfig, state: ContactState, rises: dict):
    """The tail lasts while its polarity rises above the onset bar (`rises`), and until it has not for
    `tail_frames` frames in a row: a release burst dips under the bar for a frame, and where the quiet
    rule ends a contact a frame or two before its final release, that release is its tail. Where the
    rest of the release is awaited (`tail_wait`, `_awaits_release`), it lasts until that burst comes."""
    if state.tail is None:
        return
    if rises[state.tail]:
        state.tail_quiet, state.tail_wait = 0, 0  # the awaited burst has come: it lasts while it rises
        return
    state.tail_quiet += 1
    state.tail_wait = max(state.tail_wait - 1, 0)
    if state.tail_quiet >= config.tail_frames and state.tail_wait == 0:
        state.tail = None


@dataclass
class Early:
    """A contact's first frames, as framed (OFF, ON): events, events above the background, peaks."""

    frames: int = 0
    events: list = field(default_factory=lambda: [0.0, 0.0])
    excess: list = field(default_factory=lambda: [0.0, 0.0])
    peaks: list = field(default_factory=lambda: [0.0, 0.0])

    def add(self, state: "ContactState", off: float, on: float):
        means = oriented_sums(state.polarity, state.mean_off, state.mean_on)
        for k, (count, mean) in enumerate(zip((off, on), means)):
            self.events[k] += count
            self.excess[k] += max(count - mean, 0.0)
            self.peaks[k] = max(self.peaks[k], count)
        self.frames += 1


def _follow_press(config: ContactConfig, state: ContactState, off: float, on: float):
    """In a contact's first `press_frames` frames, the press is read by the polarity with more events
    above the background since the onset, this frame's included: where that is the other one, the
    contact is read the other way from this frame on, its press's sums those of that polarity."""
    early = state.early
    if early is None or state.phase == NONE or early.frames >= config.press_frames:
        state.early = None
        return
    early.add(state, off, on)
    chosen = "on" if early.excess[1] > early.excess[0] else "off"
    if chosen == state.polarity:
        return
    state.turn(chosen)
    k = POLARITIES.index(chosen)
    # this frame is added by `_step`, as every frame of the contact is (to `pressed_sum` where it presses)
    state.off_since, state.peak_off = early.events[k] - (on if chosen == "on" else off), early.peaks[k]
    state.pressed_sum = early.excess[k] - max((on if chosen == "on" else off) - state.mean_off, 0.0)
    state.phase, state.on_run, state.released, state.held = GRASPING, 0.0, False, 0
    state.released_on, state.quiet, state.since_release, state.low = 0.0, 0.0, 0, 0  # what was read as a release was the press
    state.footprint.pressed = None  # the footprint starts again from this frame's press
    # the slip flag's numbers of this contact were read the other way: its press's peak so far is this polarity's
    state.hold_level, state.last_excess, state.slipping, state.slip_quiet = (0.0, 0.0), (0.0, 0.0), False, 0
    if state.gain.press_frames is not None:  # still measuring this contact's press (`follow_gain`)
        state.gain.press_frames, state.gain.press_peak = early.frames - 1, max(early.peaks[k] - state.mean_off, 0.0)


def _onset(config: ContactConfig, press: float, other: float, press_mean: float, other_mean: float) -> bool:
    """A contact's first frame, `press` the polarity a press makes: above its background as an onset's
    must be, and not a release burst of the other polarity."""
    return _above(config, press, press_mean) and not _brightening(config, press, other, other_mean)


def _flash(state: "ContactState", frame: np.ndarray, off: float, on: float) -> bool:
    """A frame (of FLASH_CELLS cells or more, where a contact could begin: `_may_begin`) in which at
    least FLASH_SHARE of the cells hold an event more than their rest background: a blink or flash
    that lights the whole membrane, where a press lights the object's cells. Its cells are looked at
    only where the frame's total could reach the share. Both polarities are summed: it reads the
    same however the state is turned."""
    if off + on < FLASH_SHARE * (np.size(frame) // 2):
        return False
    background = state.footprint.background
    events = np.asarray(frame, dtype=np.float32).reshape(2, -1).sum(axis=0)
    rest = 0.0 if background is None or background.shape != np.shape(frame) else background.reshape(2, -1).sum(axis=0)
    return float(np.mean(events >= rest + 1.0)) >= FLASH_SHARE


def _step(config, state, off, on, by_force) -> str:
    keep = np.exp(-1.0 / config.memory_frames)
    state.off_since = state.off_since * keep + off
    state.held_before = state.held
    if state.warmup is not None:
        _warm_up(config, state, off, on)
        return state.phase
    if state.phase == NONE:
        if _onset(config, off, on, state.mean_off, state.mean_on) and state.tail != state.polarity:
            state.phase, state.onsets, state.contact_open, state.low = GRASPING, state.onsets + 1, True, 0
            state.off_since, state.peak_off, state.on_run, state.released, state.held = off, off, 0.0, False, 0
            state.peak_force, state.press_after, state.hold_level = 0.0, 0, (0.0, 0.0)
            state.pressed_sum, state.tail_wait = max(off - state.mean_off, 0.0), 0
        else:
            _update_background(config, state, off, on)
        return state.phase
    pressing = _above(config, off, state.mean_off)
    if state.released:
        state.since_release += 1
        state.quiet += (off - state.quiet) / config.quiet_frames
    if _brightening(config, off, on, state.mean_on):
        state.on_run += on
        if not state.released:
            state.quiet, state.since_release, state.low, state.released_on = off, 0, 0, 0.0
        state.released_on += on - state.mean_on
        state.phase, state.released = RELEASING, True
        if not by_force and state.on_run >= config.release_share * state.off_since:
            state.phase, state.on_run = NONE, 0.0
    elif pressing and off > config.settled_share * state.peak_off:
        if state.phase != GRASPING:
            state.press_after = state.held
        state.phase, state.on_run, state.released = GRASPING, 0.0, False
        state.peak_off = max(state.peak_off, off)
        state.pressed_sum = state.pressed_sum * keep + off - state.mean_off
    else:
        state.on_run = 0.0
        # settled once the OFF count above the background falls: a busy background alone (hot pixels)
        # can exceed the share of a faint press's peak, which held every hold of such a camera in grasping
        if state.phase == RELEASING or off - state.mean_off < config.settled_share * (state.peak_off - state.mean_off):
            state.phase = HOLDING
    state.held = 0 if state.phase == GRASPING else state.held + 1
    return state.phase


def _brightening(config: ContactConfig, off: float, on: float, mean_on: float) -> bool:
    """An ON-dominated burst (ON above its background `mean_on`): the membrane brightens (a release),
    whatever OFF events come with it."""
    return _above(config, on, mean_on) and on > config.dominance * off


def _above(config: ContactConfig, count: float, mean: float) -> bool:
    """A count above the background `mean` by `onset_sigma` Poisson σ and by at least `min_events`."""
    return count > mean + max(config.onset_sigma * np.sqrt(mean + 1.0), config.min_events)


def end_by_force(config: ContactConfig, state: ContactState, force_n: float) -> bool:
    """After a release burst, the contact is over once the force model has read under `release_force_n`
    for `low_frames` frames in a row (a partial release or a re-grasp loosens the grip as suddenly, but
    the estimate stays up, or comes back up as the grip tightens again), or once the membrane has been
    quiet for `quiet_frames` frames since the burst while the estimate is under `quiet_force_share` of
    its peak in the contact (`peak_force`, which the caller keeps) or the release was bright
    (`quiet_release_share`). With press_polarity "either", `low_frames` frames in a row under
    `release_force_n` end a contact that has loaded, with or without a release burst (`_unloaded`), and
    the rest of a release that looks partial is awaited (`_awaits_release`)."""
    if state.phase == NONE:
        return False
    ended = _released_end(config, state, force_n) if state.released else _unloaded(config, state, force_n)
    if ended:
        state.tail_wait = config.await_frames if _awaits_release(config, state) else 0
        state.phase, state.on_run, state.released, state.low = NONE, 0.0, False, 0
    return ended


def may_end_by_force(config: ContactConfig, state: ContactState) -> bool:
    """Whether `end_by_force` may end the current contact at this frame: after a release burst, and
    throughout a contact of press_polarity "either" (`_unloaded`). A caller that runs its force model
    on runs of frames runs it frame by frame where this holds."""
    return state.released or config.press_polarity == "either"


def _released_end(config: ContactConfig, state: ContactState, force_n: float) -> bool:
    """After a release burst: the estimate low for `low_frames` frames, or the membrane quiet since the burst."""
    state.low = state.low + 1 if force_n < config.release_force_n else 0
    fallen = force_n < config.quiet_force_share * state.peak_force
    large = state.released_on >= config.quiet_release_share * max(state.peak_off - state.mean_off, 1.0)
    quiet = (state.since_release >= config.quiet_frames and (fallen or large)
             and state.quiet < state.mean_off + config.quiet_sigma * np.sqrt(state.mean_off / (2 * config.quiet_frames)))
    return state.low >= config.low_frames or quiet


AWAIT_SHARE = 0.5  # a release looks partial where its bursts brightened the membrane by under this share of what the press
# darkened it (events above the background): the quiet rule's early ends on three generators 0.09-0.30, whole releases
# mostly 0.4-1.7 but some 0.1 (a re-grasp's two presses against its last release), so the wait is bounded


def _awaits_release(config: ContactConfig, state: ContactState) -> bool:
    """Whether the quiet rule (not the estimate: it read low) ends this contact of press_polarity
    "either" at what may be a partial release: the object still held at a lower force, its final
    release to come. That burst, of the release's polarity, would read as the press of an object of
    the other kind, and the model reads 1.5-2.6 N through the rest after it. So the next such burst
    within `await_frames` is the contact's tail (`_follow_tail`). Bounded: after a whole release
    that only looked partial, the next object's press of that polarity is lost within the wait
    (waiting without a bound lost presses on two generators; docs/journal.md)."""
    return (config.press_polarity == "either" and state.released and state.low < config.low_frames
            and state.released_on < AWAIT_SHARE * state.pressed_sum)


def _unloaded(config: ContactConfig, state: ContactState, force_n: float) -> bool:
    """A contact of press_polarity "either" whose estimate, once above `release_force_n`, has read
    under it for `low_frames` frames in a row, no release burst seen: what began it may have been no
    press but the release of a contact that ended before it (the quiet rule ends some partial
    releases), read as the press of an object of the other kind, and no release burst of its own
    follows. Not before the estimate has risen: it lags a press that is still rising. A sensor of one
    polarity never reads a release as a press, and waits for the release burst: an estimate that sags
    in a hold ends nothing there."""
    if config.press_polarity != "either" or state.peak_force < config.release_force_n:
        return False
    state.low = state.low + 1 if force_n < config.release_force_n else 0
    return state.low >= config.low_frames


def _warm_up(config, state, off, on):
    state.warmup.append((off, on))
    if len(state.warmup) >= config.warmup_frames:
        state.mean_off, state.mean_on = (float(v) for v in np.median(np.asarray(state.warmup), axis=0))
        state.warmup = None


def _update_background(config, state, off, on):
    """Running mean of rest frames; a frame far above it (a creep tail, a flicker) moves it by at most 3σ."""
    rate = 1.0 / config.background_frames
    cap_off = state.mean_off + 3.0 * np.sqrt(state.mean_off + 1.0)
    cap_on = state.mean_on + 3.0 * np.sqrt(state.mean_on + 1.0)
    state.mean_off += rate * (min(off, cap_off) - state.mean_off)
    state.mean_on += rate * (min(on, cap_on) - state.mean_on)


def detect(config: ContactConfig, off: np.ndarray, on: np.ndarray, state: ContactState | None = None,
           separation: np.ndarray | None = None, slip: "SlipConfig | None" = None, force: np.ndarray | None = None,
           counts: np.ndarray | None = None):
    """Phases of a run of frames (OFF and ON counts per frame), continuing from `state`; with
    `separation` (distance of the OFF and ON centroids per frame, `frame_stats`) and `slip`, slip flags too;
    with `force` (N per frame: a force model's estimates, or the true force to measure the detection
    alone) contacts end by `end_by_force`, as `model.session.Stream` ends them, instead of `release_share`;
    with `counts` (the frames, (T, 2, H, W)) slips are judged on the footprint, as `Stream` does.

    Returns (phase array of str, onset flags (a contact begins at this frame), slip flags, the state after)."""
    state = state or ContactState.start(config)
    phases = np.empty(len(off), dtype=object)
    onsets = np.zeros(len(off), dtype=bool)
    slips = np.zeros(len(off), dtype=bool)
    off, on = np.asarray(off, dtype=np.float64).tolist(), np.asarray(on, dtype=np.float64).tolist()
    for k, (a, b) in enumerate(zip(off, on)):
        before = state.onsets
        phase = step(config, state, a, b, by_force=force is not None, frame=None if counts is None else counts[k])
        if force is not None and phase != NONE:
            state.peak_force = max(state.peak_force, float(force[k]))
            if end_by_force(config, state, float(force[k])):
                phase = NONE
        phases[k] = phase
        onsets[k] = state.onsets != before
        if slip is not None and separation is not None:
            slips[k] = slip_step(slip, state, a, b, float(separation[k]))
    return phases, onsets, slips, state


def frame_sums(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OFF and ON events per frame of (T, 2, H, W) counts."""
    sums = np.asarray(counts).reshape(len(counts), 2, -1).sum(axis=2, dtype=np.float64)
    return sums[:, 0], sums[:, 1]


# ---------------------------------------------------------------- slip
#
# A slip moves the contact patch along the membrane: its leading edge darkens (OFF events) while its
# trailing edge brightens (ON events), frame after frame. A change of the normal force darkens or
# brightens the whole rim at once, so its OFF and ON events share a centroid; a slip's are apart.
# So a frame of a contact is slipping when both polarities are active above the background and their
# centroids are at least `separation_px` apart; the flag starts at the first such frame (a slip is
# flagged within a frame of the first frame that shows it) and ends after `hold_frames` frames
# without one.


@dataclass(frozen=True)
class SlipConfig:
    min_events: float = 50.0  # OFF (and ON, unless min_events_on) events above their background (`slip_for`: from the presses)
    min_events_on: float | None = None  # ON events above their background (`slip_for`: the presses' bar times the releases' ON gain)
    noise_sigma: float = 4.0  # ... and by this many Poisson σ of their background (a bright background's noise is no slip)
    separation_px: float = 0.0  # centroids of OFF and ON events at least this far apart (frame pixels)
    hold_frames: int = 3  # a slip ends after this many frames without evidence
    keep_share: float = 0.5  # a slip under way goes on while a frame, or two together on average, pass this share of the bars
    settle_frames: int = 5  # no slip in the first frames of a hold: the object settles (rigid motion, creep)
    level_frames: int = 50  # time constant (frames) of the hold's own activity on the footprint, which a slip must rise above ...
    level_floor: float = 0.1  # ... where it exceeds this share of the bars (a quiet hold's few creep events stay counted)
    follow_presses: int = 15  # the bars follow the median of the stream's last presses, up to this many (0: fixed)
    press_off: float | None = None  # the training contacts' median press peak and release peak that set the bars
    release_on: float | None = None  # (`slip_for`; None in files written before: read back from the bars)

    @property
    def on_events(self) -> float:
        """The ON bar in force: `min_events_on`, or `min_events` in a file written before there was one."""
        return self.min_events if self.min_events_on is None else self.min_events_on

    def to_dict(self) -> dict:
        return asdict(self)


# How many events a slip makes follows the sensor's gain (its thresholds, the membrane's stiffness and
# shading, the crop and pooling) as a press does: on simulated rigs of widely varied physics the
# best fixed bar ran from 30 to 70 events while their median press peak ran from 370 to 1560. A bar at
# SLIP_SHARE of the rig's median press peak (`slip_for`) carries over from rig to rig; the floor keeps
# a background's noise from passing for a slip where presses are faint. Figures: docs/journal.md.
# A camera whose ON threshold is higher than its OFF one (or a membrane that brightens less than it
# darkens) makes fewer ON than OFF events for the same motion: the trailing edge of a slip too. The
# ON bar follows the ratio of the releases' ON peaks to the presses' OFF peaks (at most 1).
SLIP_SHARE = 0.05
SLIP_FLOOR_EVENTS = 10.0
PRESS_FRAMES = 30  # a contact's press: the peak OFF frame among its first frames
RELEASE_FRAMES = (5, 10)  # a contact's release: the peak ON frame from 5 frames before its end to 10 after


def rest_level(counts: np.ndarray, warmup_frames: int) -> float:
    """A stream's background count per frame, as the detector takes it: the median of its first
    `warmup_frames` frames (0 for no frame)."""
    return float(np.median(counts[:max(warmup_frames, 1)])) if len(counts) else 0.0


def _peaks(counts: np.ndarray, spans, warmup_frames: int) -> list[float]:
    """The largest count in each (begin, end) span of frames, above the stream's background: the
    median of its first `warmup_frames` frames, as the detector takes it."""
    counts = np.asarray(counts, dtype=np.float64)
    background = rest_level(counts, warmup_frames)
    return [float(counts[max(0, begin):end].max()) - background for begin, end in spans if end > max(0, begin)]


def press_peaks(off: np.ndarray, contacts, warmup_frames: int = ContactConfig.warmup_frames) -> list[float]:
    """Each contact's press: its peak OFF count in the first PRESS_FRAMES frames (from two before its
    start) above the stream's background. `contacts`: (start, end) frame runs of one stream's counts."""
    return _peaks(off, [(begin - 2, begin + PRESS_FRAMES) for begin, _ in contacts], warmup_frames)


def release_peaks(on: np.ndarray, contacts, warmup_frames: int = ContactConfig.warmup_frames) -> list[float]:
    """Each contact's release: its peak ON count in the RELEASE_FRAMES about its end, above the
    stream's background."""
    before, after = RELEASE_FRAMES
    return _peaks(on, [(end - before, end + after) for _, end in contacts], warmup_frames)


ONSET_FRAMES = 3  # a contact's first frames by its force, in which its press's first events are looked for (`press_polarity`)


MIXED_SHARE = 0.2  # contacts pressed clearly ON, and clearly OFF, each more than this share: objects of both kinds
CLEAR_RATIO = 2.0  # ... clearly: this many times more events of one polarity than of the other above the background


def press_polarity(streams, warmup_frames: int = ContactConfig.warmup_frames,
                   press_frames: int = ContactConfig.press_frames, shares: list | None = None) -> str:
    """"either" where more than MIXED_SHARE of the contacts of `streams` (triples of OFF per frame, ON
    per frame, contacts) press with CLEAR_RATIO times more ON than OFF events and more than that share
    with as many times more OFF (`press_shares`): a sensor that sees dark and bright objects. A
    membrane whose presses make both polarities in like numbers (printed markers lit from one side)
    is not one: its contacts' shares gather about a half. Else "on" where the presses make more ON
    than OFF events above the background (the median over the contacts of each polarity's peak in the
    ONSET_FRAMES frames from the onset and the two before it), "off" otherwise and where there is no
    contact. `shares`: `press_shares` of `streams`, where they are known."""
    shares = shares if shares is not None else press_shares(streams, warmup_frames, press_frames)
    shares = np.asarray([share for mine in shares for share in mine])
    if not len(shares):
        return "off"
    clear = CLEAR_RATIO / (1 + CLEAR_RATIO)
    if np.mean(shares > clear) > MIXED_SHARE and np.mean(shares < 1 - clear) > MIXED_SHARE:
        return "either"
    spans = [[(begin - 2, begin + ONSET_FRAMES) for begin, _ in contacts] for _, _, contacts in streams]
    off_peaks = [peak for (off, _, _), mine in zip(streams, spans) for peak in _peaks(off, mine, warmup_frames)]
    on_peaks = [peak for (_, on, _), mine in zip(streams, spans) for peak in _peaks(on, mine, warmup_frames)]
    return "on" if off_peaks and np.median(on_peaks) > np.median(off_peaks) else "off"


def press_shares(streams, warmup_frames: int = ContactConfig.warmup_frames,
                 press_frames: int = ContactConfig.press_frames) -> list[list[float]]:
    """Per stream of `streams`, each contact's press: the ON share of its events above the stream's
    background (the median of its first `warmup_frames` frames) from two frames before the onset to
    `press_frames` after it, within the contact, as the detector reads a contact's press at run time."""
    out = []
    for off, on, contacts in streams:
        off, on = np.asarray(off, dtype=np.float64), np.asarray(on, dtype=np.float64)
        quiet = [rest_level(c, warmup_frames) for c in (off, on)]
        mine = []
        for begin, end in contacts:
            span = slice(max(0, begin - 2), min(begin + press_frames, end))
            dark, bright = (float(np.clip(c[span] - q, 0.0, None).sum()) for c, q in zip((off, on), quiet))
            mine.append(bright / (dark + bright) if dark + bright > 0 else 0.0)
        out.append(mine)
    return out


def contact_polarities(shares: list) -> list[list[str]]:
    """Per stream, the polarity of each contact's press: the one with more of its events above the
    background (`press_shares`, given)."""
    return [["on" if share > 0.5 else "off" for share in mine] for mine in shares]


def oriented_streams(streams, polarity: str, shares: list | None = None) -> list:
    """`streams` (triples of OFF per frame, ON per frame, contacts) with a press's polarity first, as
    `dominance_for` and `rig_peaks` read them; with `polarity` "either", each contact by its own press
    (`shares`: `press_shares` of `streams`; a stream's bright contacts as a stream of their own, its
    channels swapped)."""
    if polarity != "either":
        return [(*oriented_sums(polarity, off, on), contacts) for off, on, contacts in streams]
    out = []
    for (off, on, contacts), polarities in zip(streams, contact_polarities(shares)):
        for kind in POLARITIES[:2]:
            mine = [contact for contact, own in zip(contacts, polarities) if own == kind]
            if mine:
                out.append((*oriented_sums(kind, off, on), mine))
    return out


RELEASE_MISS_SHARE = 0.1  # the release bar moves where more of the training releases' burst frames than this fall under it
DOMINANCE_FLOOR = 1.05  # ... but not to 1: a frame of as many ON as OFF events brightens nothing


def dominance_for(config: ContactConfig, streams) -> float:
    """The ON/OFF ratio at which a frame reads as a release burst (`dominance`) for the sensor of
    `streams` (triples of OFF per frame, ON per frame, contacts, oriented: a press's polarity first):
    the config's where at most RELEASE_MISS_SHARE of the training releases' burst frames (ON above the
    background as an onset's OFF must be, from 5 frames before a contact's end to 10 after) fall under
    it; else the geometric mean of the presses' 90th and the releases' 10th percentile of the ratio
    (presses' frames: OFF above the background, in ONSET_FRAMES about each onset), within
    DOMINANCE_FLOOR and the config's. A membrane whose releases also darken some of it (printed
    markers lit from one side) makes releases of 1.2-2 times more ON than OFF: under the bar, their
    end went unseen and the release's OFF began a contact that ran through the rest."""
    presses, releases = [], []
    before, after = RELEASE_FRAMES
    for off, on, contacts in streams:
        off, on = np.asarray(off, dtype=np.float64), np.asarray(on, dtype=np.float64)
        quiet_off, quiet_on = (rest_level(c, config.warmup_frames) for c in (off, on))
        for begin, end in contacts:
            span = slice(max(0, begin - 2), begin + ONSET_FRAMES)
            presses += [b / max(a, 1.0) for a, b in zip(off[span], on[span]) if _above(config, a, quiet_off)]
            span = slice(max(0, end - before), end + after)
            releases += [b / max(a, 1.0) for a, b in zip(off[span], on[span]) if _above(config, b, quiet_on)]
    if not presses or not releases or np.mean(np.asarray(releases) < config.dominance) <= RELEASE_MISS_SHARE:
        return config.dominance
    bar = np.sqrt(np.quantile(presses, 0.9) * np.quantile(releases, 0.1))
    return round(float(min(config.dominance, max(DOMINANCE_FLOOR, bar))), 2)


def rig_peaks(streams, warmup_frames: int = ContactConfig.warmup_frames) -> tuple:
    """(median press OFF peak, median release ON peak) over the contacts of `streams`, triples of
    (OFF per frame, ON per frame, contacts); None where there is no contact: what `slip_for` takes."""
    presses = [peak for off, _, contacts in streams for peak in press_peaks(off, contacts, warmup_frames)]
    releases = [peak for _, on, contacts in streams for peak in release_peaks(on, contacts, warmup_frames)]
    return (float(np.median(presses)) if presses else None, float(np.median(releases)) if releases else None)


def slip_for(press_off: float | None, release_on: float | None = None) -> SlipConfig:
    """The slip flag's bars for a rig whose contacts' median press peak (`press_peaks`) is `press_off`
    and median release peak (`release_peaks`) `release_on`; the default bar where they are unknown."""
    if press_off is None or not np.isfinite(press_off) or press_off <= 0:
        return SlipConfig()
    bar = max(SLIP_SHARE * float(press_off), SLIP_FLOOR_EVENTS)
    on_bar = None
    if release_on is not None and np.isfinite(release_on) and release_on > 0:
        on_bar = round(max(bar * min(float(release_on) / float(press_off), 1.0), SLIP_FLOOR_EVENTS), 1)
    return SlipConfig(min_events=round(bar, 1), min_events_on=on_bar, press_off=round(float(press_off), 1),
                      release_on=None if on_bar is None else round(float(release_on), 1))


def frame_stats(counts: np.ndarray):
    """Per frame of (T, 2, H, W) counts: OFF and ON sums and the distance between their centroids (px)."""
    counts = np.asarray(counts, dtype=np.float64)
    sums = counts.sum(axis=(2, 3))
    height, width = counts.shape[2:]
    ys, xs = np.arange(height, dtype=np.float64), np.arange(width, dtype=np.float64)
    safe = np.maximum(sums, 1.0)
    cx = (counts.sum(axis=2) * xs).sum(axis=2) / safe
    cy = (counts.sum(axis=3) * ys).sum(axis=2) / safe
    separation = np.hypot(cx[:, 0] - cx[:, 1], cy[:, 0] - cy[:, 1])
    return sums[:, 0], sums[:, 1], separation


@dataclass
class Gain:
    """How many events this stream's presses make above the background (each as `press_peaks`
    measures it on training sessions: the peak OFF count of a contact's first PRESS_FRAMES frames),
    over its last `SlipConfig.follow_presses` contacts, and the slip bars they set (None: the model's)."""

    presses: collections.deque = field(default_factory=collections.deque)
    onsets: int = 0  # the detector's onsets already seen
    press_frames: int | None = None  # frames of the current press measured so far (None: not measuring)
    press_peak: float = 0.0
    bars: SlipConfig | None = None


def follow_gain(config: SlipConfig, state: ContactState, off: float) -> SlipConfig:
    """The slip bars for this frame: `slip_for` of the median of the stream's own presses once it has
    pressed once (its releases taken in the training's proportion to its presses), the model's bars
    before that and with `follow_presses` 0. The model's bars are the training sensor's; a camera with
    other thresholds, or another membrane, makes slips of a few times more or fewer events, as it
    makes presses."""
    gain = state.gain
    if config.follow_presses <= 0:
        return config
    if state.onsets != gain.onsets:  # a contact began
        gain.onsets, gain.press_frames, gain.press_peak = state.onsets, 0, 0.0
    if gain.press_frames is not None:
        gain.press_peak, gain.press_frames = max(gain.press_peak, off - state.mean_off), gain.press_frames + 1
        if gain.press_frames == PRESS_FRAMES or state.phase == NONE:
            gain.presses.append(gain.press_peak)
            while len(gain.presses) > config.follow_presses:
                gain.presses.popleft()
            gain.press_frames, gain.bars = None, None
    if gain.bars is None and gain.presses:
        press = float(np.median(gain.presses))
        trained_press = config.press_off or config.min_events / SLIP_SHARE
        release_share = config.release_on / trained_press if config.release_on else config.on_events / config.min_events
        followed = slip_for(press, press * release_share)
        gain.bars = replace(config, min_events=followed.min_events, min_events_on=followed.min_events_on)
    return gain.bars or config


def slip_step(config: SlipConfig, state: ContactState, off: float, on: float, separation: float) -> bool:
    """Advance the slip flag by one frame whose phase `step` has just set. A slip starts in a hold
    that has settled, in no frame read as a release (on some membranes a release makes both
    polarities: the patch lets go as its rim relaxes); once started it goes on while the evidence
    does, whatever phase the counts suggest (a fast slip darkens enough to look like a press). The
    bars follow the stream's own presses (`follow_gain`). `off` and `on` as `step` takes them."""
    off, on = oriented_sums(state.polarity, off, on)
    config = follow_gain(config, state, off)
    touching = state.phase != NONE
    if state.local is not None:  # the footprint's events above its own background (`step` with the frame)
        off, on, *means = state.local
    else:
        means = (state.mean_off, state.mean_on)
    bars = (config.min_events, config.on_events)
    raw = (off - means[0], on - means[1])
    # a hold that keeps making events at the contact (a trembling object, creep, a busy membrane)
    # would pass the bars frame after frame: a slip is what rises above the hold's own level
    lifted = [max(level - config.level_floor * bar, 0.0) for level, bar in zip(state.hold_level, bars)]
    excess = (raw[0] - lifted[0], raw[1] - lifted[1])
    pair = (excess[0] + state.last_excess[0], excess[1] + state.last_excess[1])
    state.last_excess = excess
    if not touching or separation < config.separation_px:
        evidence = False
    elif state.slipping:  # hysteresis: a slip's events come unevenly, and one weak frame does not end it
        kept = (config.keep_share * bars[0], config.keep_share * bars[1])
        evidence = (_passes(config, excess, means, kept)
                    or _passes(config, pair, (2 * means[0], 2 * means[1]), (2 * kept[0], 2 * kept[1])))
    else:
        evidence = _passes(config, excess, means, bars)
    settled = state.held_before > config.settle_frames or (state.phase == GRASPING and state.press_after > config.settle_frames)
    starts = evidence and settled and state.phase != RELEASING
    state.slip_quiet = 0 if evidence else state.slip_quiet + 1
    state.slipping = touching and (starts or (state.slipping and (evidence or state.slip_quiet < config.hold_frames)))
    if state.phase == HOLDING:
        state.hold_level = tuple(level + (value - level) / config.level_frames for level, value in zip(state.hold_level, raw))
    return state.slipping


def _passes(config: SlipConfig, excess, means, bars) -> bool:
    """Both polarities' events above their backgrounds (`means`) pass their `bars` and the
    backgrounds' Poisson noise."""
    return all(above >= max(bar, config.noise_sigma * np.sqrt(mean + 1.0)) for above, mean, bar in zip(excess, means, bars))
