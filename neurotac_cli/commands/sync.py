import click

from neurotac_cli.options import Duration, FiniteRange, KeyValue, ParamType, Size, distinct_names, echo_lines, history, output_option


class Region(ParamType):
    name = "X,Y,W,H"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        try:
            parts = tuple(int(v) for v in str(value).split(","))
        except ValueError:
            parts = ()
        if len(parts) != 4 or min(parts) < 0 or parts[2] == 0 or parts[3] == 0:
            self.fail(f"expected X,Y,W,H in pixels, e.g. 0,0,60,40, got {value!r}", param, ctx)
        return parts


class SensorLag(ParamType):
    """RISE[,FALL]: the force sensor's first-order time constants, loading and unloading."""

    name = "RISE[,FALL]"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        from neurotac_cli.errors import NeurotacError
        from neurotac_cli.units import parse_duration_us

        parts = [part.strip() for part in str(value).split(",")]
        if len(parts) not in (1, 2):
            self.fail(f"expected RISE or RISE,FALL, e.g. 25ms,75ms, got {value!r}", param, ctx)
        try:
            lags = tuple(parse_duration_us(part) for part in parts)
        except NeurotacError as error:
            self.fail(str(error), param, ctx)
        if min(lags) < 0:
            self.fail(f"time constants cannot be negative, got {value!r}", param, ctx)
        return lags if len(lags) == 2 else lags * 2


@click.command()
@click.argument("events", required=False, type=click.Path(allow_dash=True))
@output_option
@click.option("--force", "force_path", type=click.Path(dir_okay=False), help="Force log (CSV, Parquet or Arrow/Feather): time and force columns, e.g. t_ms,force_N.")
@click.option("--trial", default=None, help="Trial id (default: the events file's name); a session's trials are numbered after it.")
@click.option("--label", "labels", type=KeyValue(), multiple=True, callback=distinct_names, help="A label of the trial, NAME=VALUE (repeatable): --label material=foam.")
@click.option("--manifest", type=click.Path(dir_okay=False), help="CSV with one row per recording: trial,events,force,<labels> (paths relative to it); true_* columns are ignored.")
@click.option("--method", type=click.Choice(["led", "trigger", "offset", "xcorr"]), default="led", show_default=True,
              help="led: LED-off spike of OFF events; trigger: AEDAT4 external triggers; offset: a known offset; xcorr: event rate vs |dF/dt| (the signed rate, OFF minus ON, vs dF/dt where the force sensor is slow to unload).")
@click.option("--offset", type=Duration(), default=None, help="With --method offset: the camera time of the force log's zero, e.g. 1523.4ms.")
@click.option("--region", type=Region(), default=None, help="Look for the LED (or the activity, for xcorr) only in this box X,Y,W,H.")
@click.option("--latency", type=Duration(), default=None, help="The camera's delay: led, from LED switch-off to the OFF spike's onset [default: 170us]; xcorr, of the event "
              "rate behind the force [default: 1.6ms] (both measured on the simulated DAVIS240C rig).")
@click.option("--sensor-lag", type=SensorLag(), default=None,
              help="xcorr: the force sensor's first-order time constants when loading and unloading, RISE[,FALL] "
              "(e.g. 1ms for a strain-gauge cell, 25ms,75ms for a covered FlexiForce) [default: estimated with the offset]. "
              "Give it for a sensor slower than ~2 ms that does not unload slowly: there the estimate is 0 ms and the instant "
              "comes about half the time constant early.")
@click.option("--saturation", type=FiniteRange(0), default=0.5, show_default=True,
              help="xcorr: the force, as a share of the trial's peak, at which the membrane's response to force has halved "
              "(|dF/dt| is weighted by 1/(1 + F/(share*peak)); 0 = a linear membrane).")
@click.option("--min-score", type=FiniteRange(0), default=10.0, show_default=True, help="LED method: the z-score a spike needs over its surroundings.")
@click.option("--min-coverage", type=FiniteRange(0, 1), default=0.05, show_default=True, help="LED method: the share of pixels (of the region) the spike must cover.")
@click.option("--keep-led", is_flag=True, help="LED method: keep the blink's switch-off burst in each trial (by default its events are left out and counted in the sync metadata: they mark the instant, they are not touch).")
@click.option("--trigger-type", default=None, help="Trigger method: only triggers of this type (rising, falling, pulse, ...); default any.")
@click.option("--trigger-id", type=click.IntRange(min=0), default=None,
              help="Trigger method: only triggers of this input (AEDAT 3.1) or channel (EVT 2.0/2.1/3.0); default any.")
@click.option("--median", "median_window", type=Duration(at_least_zero=True), default="10ms", show_default=True, help="Median filter window of the force (0us = none).")
@click.option("--force-time-column", default=None, help="Force log: the time column (name or 0-based index) [default: first].")
@click.option("--force-column", default=None, help="Force log: the force column (name or index) [default: second].")
@click.option("--force-time-unit", type=click.Choice(["ns", "us", "ms", "s", "min"]), default=None, help="Force log: time unit, overriding the header's suffix.")
@click.option("--force-unit", type=click.Choice(["N", "mN", "kN", "g", "kg", "lbf"], case_sensitive=False), default=None,
              help="Force log: force unit, overriding the header's suffix [default: N].")
@click.option("--sensor", type=Size(), default=None, help="Sensor WxH for files that do not declare it.")
def command(events, output, force_path, trial, labels, manifest, method, offset, region, latency, sensor_lag, saturation, min_score, min_coverage,
            keep_led, trigger_type, trigger_id, median_window, force_time_column, force_column, force_time_unit, force_unit, sensor):
    """Align camera events with a force log; cut and label trials (a recordings table).

    The LED is switched off before each grasp and the force log starts then (thesis 3.6.1): the
    switch-off is a spike of OFF events. Each trial's instant goes into its t0 column, and the
    method, score and details per trial into the neurotac:sync metadata. A long session with
    several LED blinks is cut at each blink and matched to the force log's trials (a `trial`
    column, or time restarting at 0). Each force log is checked against the recording: one that
    does not overlap it, has fewer than 10 samples or a NaN or infinite value is refused; one
    mostly outside it, negative throughout or beyond 450 N is warned about (docs/formats.md), as are a
    blink that repeats within 50 ms (a switch that bounces) and events that step back in time by a
    second or more (a camera clock that jumped).

    \b
        neurotac sync grasp.aedat --force grasp_force.csv --trial g1 --label material=foam > g1.arrows
        neurotac sync --manifest sim/manifest.csv -o recordings.parquet
        neurotac sync recordings/ -o recordings.parquet   # pairs grasp.aedat with grasp_force.csv
        neurotac import rec.aedat4 | neurotac sync --force f.csv --method trigger
    """
    from neurotac_cli import provenance, tables
    from neurotac_cli.io import manifest as recordings_in
    from neurotac_cli.ops import sync

    spec = sync.sync_method(
        method, latency, offset_us=offset, region=region, sensor_lag_us=sensor_lag, saturation=saturation, min_z=min_score,
        min_coverage=min_coverage, trigger_type=trigger_type, trigger_id=trigger_id, median_us=median_window, keep_led=keep_led)
    force_options = recordings_in.ForceOptions(force_time_column, force_column, force_time_unit, force_unit)
    events, manifest, note = recordings_in.folder_as_manifest(events, manifest, force_path)
    echo_lines("sync", [note] if note else [])
    sources = recordings_in.recording_sources(events, force_path, manifest, trial=trial, labels=dict(labels),
                                              force_options=force_options, sensor=sensor)
    recordings, warnings = sync.sync(sources, spec)
    tables.write(output, recordings, step=history(camera=provenance.checksums(recordings.schema)))
    echo_lines("sync", warnings, prefix="warning: ")
