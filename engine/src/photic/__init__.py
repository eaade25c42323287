"""Photic: physically based light in natural waters (engine package, no Blender needed)."""

__version__ = "0.1.0"
