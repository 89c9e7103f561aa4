"""neurotac: an event camera watching a silicone membrane, turned into a tactile sensor.

The library (docs/python.md) is `neurotac_cli.api`; its functions are also reachable here, loaded
on first use so that importing the package (and starting the command line) stays cheap:
`import neurotac_cli as nt; frames = nt.frame(nt.read("rec.parquet"), "10ms")`.
"""

__version__ = "0.1.0"

# neurotac_cli.api's public names; only these load it, so `from neurotac_cli import tables` and the
# like never do
API = ("read", "write", "import_camera", "simulate", "sync", "frame", "crop", "augment", "counts", "train",
       "evaluate", "load_model", "save_model", "Stepper", "to_tonic", "from_tonic", "tonic_sensor_size", "events_of",
       "render", "Rotate", "Resize", "FrameShift", "EventShift", "Noise", "TONIC_DTYPE")


def __getattr__(name: str):
    if name not in API:
        raise AttributeError(f"module 'neurotac_cli' has no attribute {name!r}")
    import importlib

    api = importlib.import_module("neurotac_cli.api")
    return getattr(api, name)
