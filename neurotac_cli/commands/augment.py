"""`neurotac augment`: the thesis's chapter-5 augmentations as a filter on frames tables."""

import click

from neurotac_cli.options import Finite, FiniteRange, KeyValue, echo_lines, history, input_paths, output_option, seed_option


@click.command()
@input_paths
@output_option
@click.option("--rotate", "rotate", type=FiniteRange(-360, 360), default=None, metavar="DEG",
              help="Rotate every frame of a trial by DEG degrees about its contact centre (clockwise on screen).")
@click.option("--rotate-range", "rotate_range", type=FiniteRange(-360, 360), nargs=2, default=None, metavar="A B",
              help="Rotate each copy of a trial by one angle drawn uniformly from [A, B] degrees (thesis: 0 45).")
@click.option("--resize", "resize", type=Finite(above=0), default=None, metavar="BETA",
              help="Scale about the contact centre by BETA > 0 (>1 larger; thesis 1.25 small objects, 0.83 large), "
                   "bilinear, zero margin.")
@click.option("--preserve-total", is_flag=True,
              help="After rotating or resizing, rescale each frame and channel to its original event count.")
@click.option("--noise", "noise", type=click.Path(dir_okay=False, exists=True), default=None, metavar="FILE",
              help="Add background-noise frames from FILE, a frames table of a still recording framed and cropped "
                   "like the input; a random stretch of it per copy.")
@click.option("--fs", "fs", type=int, default=None, metavar="J",
              help="Frame shifting: move frames J later (J<0: earlier), zero fill; labels stay (thesis best: -1).")
@click.option("--tes", "tes", type=(int, FiniteRange(0, 1)), default=None, metavar="J ZETA",
              help="Temporal event shifting: move round(ZETA*n) random events of each frame and channel J frames "
                   "(thesis best: -2 0.5).")
@click.option("--combine", type=click.Choice(["independent", "hybrid"]), default="independent", show_default=True,
              help="independent: each method makes its own copies; hybrid: every copy gets all methods in turn.")
@click.option("--copies", type=click.IntRange(min=1), default=1, show_default=True,
              help="Copies of every trial per method (independent) or in all (hybrid).")
@click.option("--where", "where", type=KeyValue(), multiple=True,
              help="Augment only trials with this label value, e.g. object=bolt12 (repeat: any of them); "
                   "the others pass unchanged.")
@click.option("--only-augmented", is_flag=True, help="Write the copies only, not the original trials.")
@seed_option
def command(paths, output, rotate, rotate_range, resize, preserve_total, noise, fs, tes, combine, copies,
            where, only_augmented, seed):
    """Make augmented copies of every trial of a frames table (thesis chapter 5).

    Copies get the trial id TRIAL~WHAT#COPY and the columns source_trial (the original trial) and
    augment (what was done); force, phase and labels stay in place. With several methods,
    --combine independent makes copies per method; hybrid composes rotate, resize, fs, tes, noise.
    Events pushed past the first or last frame leave the trial and are counted in the history.

    \b
        neurotac frame --window 10ms < rec.parquet | neurotac augment --tes -2 0.5 --copies 2
        neurotac augment --resize 1.25 --fs -1 --seed 3 -o train_aug.parquet train.parquet
    """
    from neurotac_cli import tables
    from neurotac_cli.ops import augment

    angles = [rotate] if rotate is not None else list(rotate_range or ())
    rotation = f"--rotate {rotate:g}" if rotate is not None else "--rotate-range " + " ".join(f"{a:g}" for a in angles)
    whole_turns = bool(angles) and min(angles) == max(angles) and angles[0] % 360 == 0  # 0, 360 or -360 degrees
    tes_said = None if tes is None else "--tes with J 0" if tes[0] == 0 else "--tes with ZETA 0"  # one method, one entry
    unchanged = [name for name, same in (("--fs 0", fs == 0), (tes_said, tes is not None and 0 in (tes[0], tes[1])),
                                         (rotation, whole_turns), ("--resize 1", resize == 1))
                 if same]
    methods = sum(value is not None for value in (rotate, rotate_range, resize, fs, tes, noise))
    augment.check_changes(unchanged, methods, combine)
    request = augment.Augmentation(rotate=rotate, rotate_range=rotate_range or None, resize=resize,
                                   preserve_total=preserve_total, fs=fs, tes=tes, combine=combine, copies=copies,
                                   where=where, keep_original=not only_augmented, seed=seed, noise=noise)
    frames = tables.read(paths, kind="frames")
    noise_frames = tables.read([noise], kind="frames") if noise else None
    result, counted, warnings = augment.augment(frames, request, noise_frames)
    echo_lines("augment", warnings, prefix="warning: ")
    tables.write(output, result, step=history(counted=counted))
