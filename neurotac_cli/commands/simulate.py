"""`neurotac simulate`: grasps from a physical model, written as a rig writes them."""

import sys

import click

from neurotac_cli.options import Duration, KeyValue, Size, distinct_names, echo_lines, history, output_option, seed_option


def _progress_printer():
    """A progress line on stderr when stderr is a terminal; otherwise nothing."""
    from neurotac_cli.tables import is_terminal

    if not is_terminal(sys.stderr):
        return None

    def show(done, total):
        end = "\n" if done >= total else ""
        click.echo(f"\rsimulate: step {done}/{total} ({100 * done // max(1, total)}%)", err=True, nl=False)
        if end:
            click.echo("", err=True)

    return show


# The objects a session draws from when neither --objects nor --preset says: every material, flat and rounded faces, three bolt sizes.
SESSION_OBJECTS = ("foam:hex:1", "silicone:hex:1", "rubber:hex:1", "steel:hex:1", "steel:bolt8:1", "steel:bolt12:1",
                   "steel:bolt16:1", "rubber:sphere10:1", "silicone:sphere16:1")


SESSION_ONLY = ("grasps", "sessions", "duration", "illumination_drift")  # options that apply with --session alone

# A session is one AEDAT 2.0 file, whose 32-bit µs clock (io.writers.AEDAT2_LAST_US) runs 71.6 min, and
# each grasp rests at least 50 ms before it (sim.config.SESSION_REST_FLOOR_US): no more grasps fit in one.
# Written out, not imported, so that `simulate --help` loads neither numpy nor pyarrow.
MAX_GRASPS = 0xFFFFFFFF // 50_000
MAX_FORCE_N = 450  # sim.config.validate's bound on force_max_n: the largest range of the rig's force sensors


@click.command()
@click.option("--preset", type=click.Choice(["ch3", "ch4", "ch5"]), default=None,
              help="Experiment design of the thesis: ch3 (48 hex prisms of 4 materials, FlexiForce), "
                   "ch4 (35 bolts of 8/12/16 mm, Nano17), ch5 (60 bolts of 12/15/18 mm, 0-25 N, two gripper forces).  "
                   "[default: ch4; with --session, ch4's rig with a mixed pool of objects of every material]")
@click.option("--session", is_flag=True,
              help="Write sessions instead of trials: one camera file and force log per session, one LED blink at its "
                   "start, then --grasps grasps after rests, with re-grasps, force changes, partial releases and slips "
                   "(needs --out; manifest.csv has a row per session, grasps.csv every grasp's and slip's true times).")
@click.option("--grasps", type=click.IntRange(min=0, max=MAX_GRASPS), default=50, show_default=True,
              help="With --session: grasps per session, objects drawn from --objects (or the preset's groups), weighted by count; "
                   f"at most {MAX_GRASPS}, what one AEDAT 2.0 file's 71.6-minute clock holds at the shortest rests (a session "
                   "planned to record longer is refused before it is simulated; about 800 grasps fit at the default rests and holds).")
@click.option("--sessions", type=click.IntRange(min=1), default=1, show_default=True,
              help="With --session: how many sessions to write (session00, session01, ...), each its own seed stream.")
@click.option("--duration", type=Duration(positive=True), default=None,
              help="With --session: the shortest session, e.g. 5min (the last rest is stretched; with --grasps 0, a session at rest).")
@click.option("--illumination-drift", type=float, default=None, metavar="SHARE",
              help="With --session: slow drift of the lighting, its relative amplitude (0.05 = +-5% over "
                   "illumination_period_us, 60 s).")
@click.option("--gripper", type=click.Choice(["position", "force"]), default=None,
              help="position: the squeeze relaxes with the material while held (the thesis's rig); force: a "
                   "force-controlled grip holds each grasp's peak force, drawn independently of the material.  [default: position]")
@click.option("--vary", default=None, metavar="FAMILY,...|all",
              help="Domain randomisation: draw these parameter families per trial (per session with --session) from "
                   "wide ranges: pixels, membrane, optics, noise, sensor, objects, or all (ranges: docs/simulator.md).")
@click.option("--hold-out", "hold_out", default=None, metavar="FAMILY",
              help="Training data: draw FAMILY from the lower two thirds of each of its ranges only (varied even if not in --vary).")
@click.option("--unseen", default=None, metavar="FAMILY",
              help="Test data: draw FAMILY from the upper third of each of its ranges only, physics --hold-out training never saw.")
@click.option("--rigs", type=click.IntRange(min=1), default=None,
              help="With --vary: deal the grasps in turn to this many rigs, each one draw of the physics shared by its grasps "
                   "(a lab's sensors, each with several grasps of every group), labelled `rig` (rig1-XXXXXX, ...: the suffix a digest of the rig's physics): "
                   "training data for `train --adapt-by rig`.")
@click.option("--trials", type=click.IntRange(min=1), default=None,
              help="Simulate only this many grasps, spread over the preset's groups in turn (a small, fast data set).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Write the rig's files to this folder: <trial>.aedat (AEDAT 2.0), <trial>_force.csv, "
                   "manifest.csv and still.aedat.")
@click.option("--synced", is_flag=True,
              help="Write a `recordings` table (trials cut at the true LED-off instant) to stdout or -o.")
@output_option
@seed_option
@click.option("--objects", "groups", default=None, metavar="MAT:OBJ:N,...",
              help="Trial groups instead of the preset's, e.g. steel:bolt8:5,foam:hex:5,rubber:sphere10:3 "
                   "(objects: hex, hexSIZE_MM, boltSIZE_MM, sphereDIAMETER_MM; add :NAME=VALUE for a label); "
                   "at most 20000 trials in one run; with --session the counts weigh the draw.")
@click.option("--force-range", default=None, metavar="LOW..HIGH",
              help="Peak force of each grasp drawn uniformly in this range, in newtons, e.g. 0.5..3.7; HIGH at most "
                   f"{MAX_FORCE_N} N, the largest range of the rig's force sensors (the presets go up to 25 N).")
@click.option("--hold", type=Duration(), default=None, help="Holding phase length, with its unit: 700ms.")
@click.option("--force-sensor", type=click.Choice(["nano17", "flexiforce"]), default=None,
              help="Force sensor model: fast F/T cell or slow, hysteretic piezoresistive sensor.")
@click.option("--background-rate", type=float, default=None, help="Background activity per pixel, in Hz (0.1; at most 50).")
@click.option("--sensor", "sensor_size", type=Size(), default=None, help="Sensor size in pixels (240x180).")
@click.option("--set", "settings", type=KeyValue(), multiple=True, callback=distinct_names,
              help="Any simulator parameter by name, e.g. --set on_threshold=0.3 --set creep_us=150ms "
                   "(the full list with units and sources: docs/simulator.md). With --vary, a family's parameter drawn as a "
                   "factor is drawn about the value set; one drawn outright, or a session's parameter without --session, is "
                   "refused: it would change nothing.")
@click.option("--keep-led", is_flag=True, help="With --synced: keep the LED blink's events in each trial, as `sync --keep-led` does (by default they are left out: they mark the instant, they are not touch).")
def command(preset, session, grasps, sessions, duration, illumination_drift, gripper, vary, hold_out, unseen, rigs, trials,
            out_dir, synced, output, seed, groups, force_range, hold, force_sensor, background_rate, sensor_size, settings,
            keep_led):
    """Simulate grasps on the neuromorphic tactile sensor: camera files, force logs and a manifest.

    A physical model (contact mechanics of the object on the silicone membrane, optics, a DVS pixel
    model, force sensors) writes what the thesis's rig wrote: one AEDAT 2.0 file per grasp on the
    camera's own clock, starting with an LED blink whose switch-off is a spike of OFF events, and a
    500 Hz force log whose time 0 is that switch-off. The same seed writes the same bytes.

    With --session, one long recording per session instead: grasps of mixed objects at random times,
    speeds and forces, with the events a robot's grip has while it holds. `--vary` draws the physics
    from wide ranges (domain randomisation); `--hold-out`/`--unseen` keep one family's training and
    test ranges apart.

    \b
        neurotac simulate --preset ch4 --seed 1 --out sim/
        neurotac simulate --preset ch3 --trials 8 --synced | neurotac frame --window 7ms
        neurotac simulate --session --grasps 50 --duration 5min --seed 3 --out s/
        neurotac sync --manifest s/manifest.csv | neurotac crop --pool 6x6 | neurotac frame --window 10ms --phases session
        neurotac simulate --trials 24 --vary all --hold-out membrane --gripper force --out train/
        neurotac simulate --preset ch3 --gripper force --vary all --rigs 8 --synced -o rigs.parquet
    """
    from neurotac_cli import tables
    from neurotac_cli.errors import UsageError
    from neurotac_cli.sim.config import preset_config

    _check_mode(session, out_dir, synced, output, trials, grasps, sessions, duration, illumination_drift, hold, keep_led)
    variation = _check_settings(settings, session, vary, hold_out, unseen, background_rate)
    overrides = _overrides(settings, groups, session and preset is None, gripper, illumination_drift, force_range, hold,
                           force_sensor, background_rate, sensor_size)
    config = preset_config(preset or "ch4", **overrides)
    if rigs and variation is None:
        raise UsageError("--rigs deals the grasps to rigs of drawn physics: give --vary (or --hold-out / --unseen) too")
    if rigs and session:
        raise UsageError("--rigs is for trials; with --session each session draws its own physics (--vary)")
    if session:
        from neurotac_cli.sim.session import write_sessions

        notes = []
        with tables.together():  # a folder of one run's sessions and manifest, never of two
            write_sessions(config, seed, grasps, out_dir, sessions, variation, duration or 0, _progress_printer(), notes=notes)
        echo_lines("simulate", notes, "warning: ")
        return
    if synced and output in (None, "-"):
        tables.refuse_terminal()  # before minutes of work, not after
    elif synced:
        tables.check_folder(output)

    from neurotac_cli.sim.run import prepare_folder, recordings, simulate, write_dataset

    if out_dir:
        prepare_folder(out_dir)
    simulation = simulate(config, seed=seed, trials=trials, progress=_progress_printer(), variation=variation, rigs=rigs or 0)
    with tables.together():  # the folder's files and the table are one simulation's, or the last one's
        if out_dir:
            write_dataset(simulation, out_dir)
        if synced:
            tables.write(output, recordings(simulation, keep_led=keep_led), step=history(preset=preset or "ch4", unused=SESSION_ONLY))


def _overrides(settings, groups, mixed_pool, gripper, illumination_drift, force_range, hold, force_sensor,
               background_rate, sensor_size) -> dict:
    """The simulator parameters the options set, by field name."""
    from neurotac_cli.sim.config import parse_value

    overrides = {name: parse_value(name, value) for name, value in settings}
    if groups:
        overrides["groups"] = parse_value("groups", groups)
    elif mixed_pool:
        overrides["groups"] = SESSION_OBJECTS
    if gripper:
        overrides["gripper"] = gripper
    if illumination_drift is not None:
        overrides["illumination_drift"] = illumination_drift
    if force_range:
        overrides["force_min_n"], overrides["force_max_n"] = _force_range(force_range)
    if hold is not None:
        overrides["hold_us"] = hold
    if force_sensor:
        overrides["force_sensor"] = force_sensor
    if background_rate is not None:
        overrides["background_rate_hz"] = background_rate
    if sensor_size:
        overrides["sensor_width"], overrides["sensor_height"] = sensor_size
    return overrides


def _check_mode(session, out_dir, synced, output, trials, grasps, sessions, duration, illumination_drift, hold, keep_led):
    """Options that belong to one mode only are refused in the other, rather than ignored."""
    from neurotac_cli.errors import UsageError

    if session:
        if not out_dir:
            raise UsageError("--session writes files: give --out DIR (then `neurotac sync --manifest DIR/manifest.csv`)")
        if synced or output or trials is not None or keep_led:
            raise UsageError("--synced, -o, --keep-led and --trials are for trials, not --session (sync the session with "
                                "`neurotac sync --manifest DIR/manifest.csv`; --grasps sets a session's grasps)")
        if hold is not None:
            raise UsageError("--hold sets a trial's hold; a session draws each grasp's hold from session_hold_us "
                                "(e.g. --set session_hold_us=1s..4s)")
        return
    if not out_dir and not synced:
        raise UsageError("nothing to write (give --out DIR for the rig's files, --synced for a recordings table, or both)")
    if output and not synced:
        raise UsageError("-o writes the --synced table; add --synced, or use --out DIR for the rig's files")
    if keep_led and not synced:
        raise UsageError("--keep-led keeps the blink in the --synced table's trials; add --synced (the rig's files under "
                         "--out always hold the blink: `sync --keep-led` keeps it there)")
    ctx = click.get_current_context()
    given = [f"--{name.replace('_', '-')}" for name in ("grasps", "sessions")
             if ctx.get_parameter_source(name) != click.core.ParameterSource.DEFAULT]
    given += [flag for flag, value in (("--duration", duration), ("--illumination-drift", illumination_drift)) if value is not None]
    if given:
        raise UsageError(f"{', '.join(given)} only {'apply' if len(given) > 1 else 'applies'} with --session (add --session, or "
                         "leave them out)")


def _check_settings(settings, session, vary, hold_out, unseen, background_rate):
    """The variation the options ask for; a --set that would change nothing is refused, not ignored:
    a session's parameter in a run of trials, or a parameter that --vary draws outright (a factor
    family's is drawn about it)."""
    from neurotac_cli.errors import UsageError
    from neurotac_cli.sim.config import SESSION_PARAMETERS, TRIAL_PARAMETERS
    from neurotac_cli.sim.physics import FAMILIES, parse_variation

    names = [name for name, _ in settings]
    idle = [name for name in names if name in (TRIAL_PARAMETERS if session else SESSION_PARAMETERS)]
    if idle:
        where = "without --session (a session draws its grasps' timing itself)" if session else "with --session"
        raise UsageError(f"--set {', '.join(idle)}: {'these only apply' if len(idle) > 1 else 'it only applies'} {where} "
                         f"({'leave them out' if session else 'add --session, or leave them out'})")
    given = {name: f"--set {name}" for name in names}
    if background_rate is not None:
        given["background_rate_hz"] = "--background-rate"
    variation = parse_variation(vary, hold_out, unseen)
    replaced = variation.replaces(list(given)) if variation is not None else []
    if replaced:
        name, family = replaced[0]
        spec = FAMILIES[family][name]
        drawn_by = ("--vary" if family != variation.held_out else "--hold-out" if variation.side == "seen" else "--unseen")
        raise UsageError(f"{given[name]}: {drawn_by} draws it ({family}: {spec.low:g} to {spec.high:g}), which would "
                         f"replace the value given; leave {family} out of {drawn_by}, or {given[name]} out")
    return variation


def _force_range(text):
    from neurotac_cli.errors import UsageError

    parts = str(text).replace("N", "").split("..")
    try:
        low, high = (float(part) for part in parts)
    except ValueError:
        raise UsageError(f"cannot read force range {text!r} (write LOW..HIGH in newtons, e.g. 0.5..3.7)") from None
    return low, high
