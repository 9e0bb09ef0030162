#!/usr/bin/env python3
"""Kept for old command lines: ``python scripts/train_per_density.py …`` is ``fogsim study …``."""
import sys

from fogsim.cli import main

if __name__ == "__main__":
    sys.exit(main(["study", *sys.argv[1:]]))
