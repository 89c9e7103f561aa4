"""neurotac: an event camera watching a silicone membrane, turned into a tactile sensor."""

__version__ = "0.1.0"
