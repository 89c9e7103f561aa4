"""`neurotac augment`: the thesis's chapter-5 augmentations as a filter on frames tables."""

import click

from neurotac_cli.options import KeyValue, input_paths, output_option, seed_option

LOSS_WARNING = 0.05  # warn on stderr when a method pushes out more than this share of its input events


@click.command()
@input_paths
@output_option
@click.option("--rotate", "rotate", type=float, default=None, metavar="DEG",
              help="Rotate every frame of a trial by DEG degrees about its contact centre (clockwise on screen).")
@click.option("--rotate-range", "rotate_range", type=float, nargs=2, default=None, metavar="A B",
              help="Rotate each copy of a trial by one angle drawn uniformly from [A, B] degrees (thesis: 0 45).")
@click.option("--resize", "beta", type=click.FloatRange(min=0, min_open=True), default=None, metavar="BETA",
              help="Scale about the contact centre by BETA (>1 larger; thesis 1.25 small objects, 0.83 large), "
                   "bilinear, zero margin.")
@click.option("--preserve-total", is_flag=True,
              help="After rotating or resizing, rescale each frame and channel to its original event count.")
@click.option("--noise", "noise_path", type=click.Path(dir_okay=False, exists=True), default=None, metavar="FILE",
              help="Add background-noise frames from FILE, a frames table of a still recording framed and cropped "
                   "like the input; a random stretch of it per copy.")
@click.option("--fs", "fs", type=int, default=None, metavar="J",
              help="Frame shifting: move frames J later (J<0: earlier), zero fill; labels stay (thesis best: -1).")
@click.option("--tes", "tes", type=(int, click.FloatRange(0, 1)), default=None, metavar="J ZETA",
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
def command(paths, output, rotate, rotate_range, beta, preserve_total, noise_path, fs, tes, combine, copies,
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

    if rotate is None and not rotate_range and beta is None and noise_path is None and fs is None and tes is None:
        raise click.UsageError("give at least one of --rotate, --rotate-range, --resize, --noise, --fs, --tes")
    if rotate is not None and rotate_range:
        raise click.UsageError("give --rotate or --rotate-range, not both")
    if rotate_range and rotate_range[1] < rotate_range[0]:
        raise click.UsageError(f"--rotate-range {rotate_range[0]:g} {rotate_range[1]:g} is empty; give the smaller angle first")

    methods = []
    if rotate is not None:
        methods.append(augment.Rotate(rotate, preserve_total=preserve_total))
    if rotate_range:
        methods.append(augment.Rotate(*rotate_range, preserve_total=preserve_total))
    if beta is not None:
        methods.append(augment.Resize(beta, preserve_total=preserve_total))
    if fs is not None:
        methods.append(augment.FrameShift(fs))
    if tes is not None:
        methods.append(augment.EventShift(*tes))

    frames = tables.read(paths, kind="frames")
    if noise_path is not None:
        noise = tables.read([noise_path], kind="frames")
        methods.append(augment.Noise(tuple(augment.noise_pool(noise, frames.schema))))
    result, counted = augment.augment_frames(
        frames, methods, copies=copies, combine=combine, keep_original=not only_augmented, seed=seed,
        where=list(where),
    )
    for name, entry in counted.items():
        lost = entry.get("events_lost", 0)
        if entry["events_in"] and lost > LOSS_WARNING * entry["events_in"]:
            click.echo(
                f"neurotac augment: warning: {name} pushed {lost} of {entry['events_in']} events out of the frames",
                err=True,
            )
    args = {
        "rotate": rotate, "rotate_range": list(rotate_range) if rotate_range else None, "resize": beta,
        "preserve_total": preserve_total, "noise": noise_path, "fs": fs, "tes": list(tes) if tes else None,
        "combine": combine, "copies": copies, "where": [f"{k}={v}" for k, v in where] or None, "only_augmented": only_augmented, "seed": seed, "counted": counted,
    }
    tables.write(output, result, step=("augment", {key: value for key, value in args.items() if value is not None}))
