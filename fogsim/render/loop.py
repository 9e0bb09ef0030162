"""The one frame loop of every front door (``fogsim render``, ``render_batch.py``, the add-on).

Failure policy, the same everywhere: a frame that fails is reported, counted and skipped,
and the loop goes on with the next one (a long run must not die on one bad frame; the
next run retries it, since only committed frames are skipped). After the loop the
dataset-wide files (COCO, YAMLs, splits, manifest, contact sheet) are written over every
committed frame — except in a shard of an array job, where one ``--finalize-only`` run
writes them once all shards are done.

The loop only needs a job with ``todo`` (frame indices left), ``step()`` (render and commit
the next frame, returning its meta record) and ``finish()``; it imports no bpy.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

from fogsim.errors import unexpected


@dataclass
class FrameLoop:
    """Steps a render job frame by frame, collecting failures."""

    job: object
    failed: list[tuple[int, str]] = field(default_factory=list)
    done: int = 0
    summary: dict | None = None

    def __post_init__(self):
        self.total = len(self.job.todo)

    @property
    def remaining(self) -> int:
        return len(self.job.todo)

    def step(self) -> tuple[int, dict | None, str | None]:
        """Render the next frame: ``(index, meta, None)`` or, when it failed, ``(index, None, error)``."""
        index = self.job.todo[0]
        try:
            meta = self.job.step()
        except Exception as exc:  # one bad frame must not stop a long run; it is reported
            if index in self.job.todo:
                self.job.todo.remove(index)
            error = unexpected(exc)
            self.failed.append((index, error))
            return index, None, error
        self.done += 1
        return index, meta, None

    def run(self, on_frame: Callable[[int, dict | None, str | None], None] | None = None,
            should_stop: Callable[[], bool] = lambda: False) -> None:
        """Step until no frame is left or ``should_stop()``; ``on_frame`` sees every step."""
        while self.job.todo and not should_stop():
            result = self.step()
            if on_frame is not None:
                on_frame(*result)

    def finish(self, sharded: bool) -> bool:
        """Write the dataset-wide files unless this is a shard; True when they were written
        (``summary``: what ``job.finish()`` returned, ``dataset.json``'s content)."""
        if sharded or not self.job.layout.done_frames():
            return False
        self.summary = self.job.finish()
        return True


def frame_log(meta: dict) -> str:
    """One line per committed frame: time per stage and the number of kept boxes."""
    stages = ", ".join(f"{k} {v:.2f}s" for k, v in meta["timings_s"].items())
    return f"frame {meta['frame']}: {stages}; {sum(r['kept'] for r in meta['objects'])} boxes"
