"""The real 3D-printer bench: a Marlin printer with an indenter and a MuCa board."""
