"""``python -m fogsim …`` is ``fogsim …``."""
import sys

from fogsim.cli import main

sys.exit(main())
