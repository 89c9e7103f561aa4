"""The registry of camera-format readers: format name -> `open_<format>(path, head, sensor) -> Decoded`."""

from neurotac_cli.io.aedat2 import open_aedat2
from neurotac_cli.io.aedat3 import open_aedat3
from neurotac_cli.io.aedat4 import open_aedat4
from neurotac_cli.io.eventstream import open_es
from neurotac_cli.io.hdf5 import open_hdf5
from neurotac_cli.io.prophesee import open_dat, open_evt2, open_evt3, open_evt21
from neurotac_cli.io.text import open_text

OPENERS = {
    "aedat2": open_aedat2,
    "aedat3": open_aedat3,
    "aedat4": open_aedat4,
    "evt2": open_evt2,
    "evt21": open_evt21,
    "evt3": open_evt3,
    "dat": open_dat,
    "es": open_es,
    "csv": open_text,
    "text": open_text,
    "hdf5": open_hdf5,
}
