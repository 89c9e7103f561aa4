"""`neurotac render`: draw a table as PNG, GIF or MP4."""

import click

from neurotac_cli.options import Duration, FiniteRange, IntTuple, Size, input_paths


@click.command()
@input_paths
@click.option("-o", "--output", type=click.Path(dir_okay=False, writable=True), required=True,
              help="The picture to write: .png (one figure), .gif or .mp4 (one picture per frame or slice).")
@click.option("--view", type=click.Choice(["montage", "crop", "augmented"]), default="montage", show_default=True,
              help="montage: frames, or time slices of events, with the force under them; crop: the crop box over "
              "the accumulated counts; augmented: an augmented copy under its source.")
@click.option("--trial", default=None, help="The trial to draw (default: the first; for --view augmented a copy or its source).")
@click.option("--slices", type=click.IntRange(1, 1000), default=8, show_default=True,
              help="Events and recordings: cut the trial into this many equal time slices.")
@click.option("--slice", "slice_us", type=Duration(positive=True), default=None, help="Events and recordings: slices of this length instead (e.g. 50ms).")
@click.option("--columns", type=click.IntRange(1, 60), default=8, show_default=True, help="Tiles per row of a PNG montage.")
@click.option("--every", type=click.IntRange(1), default=1, show_default=True, help="Draw every n-th frame or slice.")
@click.option("--fps", type=FiniteRange(0.1, 120), default=10.0, show_default=True, help="Pictures per second of a GIF or MP4.")
@click.option("--box", type=IntTuple(4, "60,30,115,115", "X,Y,W,H"), default=None, help="--view crop: the box, as `neurotac crop --box`.")
@click.option("--size", type=Size(), default=None, help="--view crop: a WxH box centred at --center, as `neurotac crop --size`.")
@click.option("--center", type=IntTuple(2, "120,90", "X,Y|auto", words=("auto",)), default=None,
              help="--view crop: centre of the --size box, X,Y or `auto` (the contact area of the whole input, as crop finds it).")
def command(paths, output, view, trial, slices, slice_us, columns, every, fps, box, size, center):
    """Draw events, recordings or frames: ON/OFF counts over time, the force under them, a crop box,
    an augmented copy beside its source.

    ON counts are red and OFF counts blue on white, on a square-root scale with a colour bar per
    channel (events per pixel); the force strip is in newtons over ms from the trial's zero, the
    phases shaded. A one-line summary goes to stderr; a GIF or MP4 shows its progress there too, on a
    terminal or with NEUROTAC_PROGRESS=1 set.

    \b
        neurotac import rec.aedat | neurotac render --slices 12 -o slices.png
        neurotac render frames.arrows --trial steel-bolt12-01 --every 3 -o montage.png
        neurotac render frames.arrows --view crop --size 115x115 --center auto -o box.png
        neurotac augment --rotate 30 < frames.arrows | neurotac render --view augmented -o rotated.gif
    """
    from neurotac_cli import rendering as rd, schema as sch, tables
    from neurotac_cli.ops.crop import CropSpec

    ctx = click.get_current_context()
    given = {name for name in ("fps", "slices", "slice_us") if ctx.get_parameter_source(name) != click.core.ParameterSource.DEFAULT}
    given |= {name for name, value in (("box", box), ("size", size), ("center", center)) if value is not None}
    rd.check_options(output, view, given)
    crop = CropSpec(box=box, size=size, center=center) if box or size else None
    spec = rd.RenderSpec(view=view, trial=trial, slices=slices, slice_us=slice_us, columns=columns, every=every, fps=fps, crop=crop)
    table = tables.read(paths, kind=("frames", "recordings", "events"))
    rd.check_slicing(sch.table_kind(table.schema), given)
    done = rd.render(table, output, spec)
    click.echo(f"neurotac render: wrote {output}: {done['view']} of trial {done['trial']!r}, {done['pictures']} "
               f"picture{'s' if done['pictures'] > 1 else ''} of {done['width']}x{done['height']} pixels", err=True)
    if done["left_out"]:
        click.echo(f"neurotac render: warning: {done['left_out']} more tiles that --every picks were not drawn (a PNG holds "
                   "--columns tiles of an augmented pair, 60 of a montage); raise --every or --columns, or write .gif or .mp4 "
                   "for all of them", err=True)
