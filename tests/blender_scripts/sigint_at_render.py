"""Test hook: Ctrl-C (SIGINT to this process) from inside its Nth render (``SIGINT_AT_RENDER=N``).

Loaded before the command under test — ``python sigint_at_render.py ARGV…`` runs ``fogsim ARGV…``
(bpy module), ``blender -b --python sigint_at_render.py -P scripts/render_batch.py -- …`` (Blender)
or ``-- addon`` (imported by ``addon_interrupt.py``) — it registers a ``render_pre`` handler: Blender
calls it inside ``bpy.ops.render.render``, so the signal arrives during a render by construction,
not after a time, on any machine.
"""
import os
import signal
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
for site in sorted((ROOT / ".venv" / "lib").glob("python3*/site-packages")):
    sys.path.insert(1, str(site))

import bpy  # noqa: E402

AT = int(os.environ["SIGINT_AT_RENDER"])
_count = [0]


@bpy.app.handlers.persistent  # kept when scene mode opens the user's .blend
def _pre(*_):
    _count[0] += 1
    if _count[0] == AT:
        os.kill(os.getpid(), signal.SIGINT)


bpy.app.handlers.render_pre.append(_pre)

if __name__ == "__main__" and "--" not in sys.argv and not Path(sys.argv[0]).name.startswith("blender"):
    from fogsim.cli import main

    sys.exit(main(sys.argv[1:]))
