"""Progress a person can see: the stage a long command is in and how many are done, as a tqdm
bar on stderr; nothing when stderr is not a terminal (a log, a pipe) or with ``--quiet``.

    with progress(("read", "surfaces", "write"), quiet) as bar:
        bar.start("read"); ...
        bar.start("surfaces"); ...
"""
from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator, Sequence


def bar_disabled(quiet: bool) -> bool | None:
    """tqdm's ``disable`` for a bar: off with ``quiet``, else shown only on a terminal (None)."""
    return True if quiet else None


class StageBar:
    """A bar of named stages; :meth:`start` ends the stage running and starts the next."""

    def __init__(self, stages: Sequence[str], quiet: bool = False):
        from tqdm import tqdm

        self.stages = tuple(stages)
        self._started = False
        self._bar = tqdm(total=len(self.stages), desc=self.stages[0], unit="stage", file=sys.stderr,
                         disable=bar_disabled(quiet), leave=False,
                         bar_format="carbody {desc} {bar} {elapsed}")

    def start(self, label: str) -> None:
        """Mark the stage running as done and show ``label`` as the one now running."""
        if self._started:
            self._bar.update(1)
        self._started = True
        self._bar.set_description_str(f"{label} (stage {self._bar.n + 1} of {len(self.stages)})")

    def close(self) -> None:
        if self._started:
            self._bar.update(1)
        self._bar.close()


@contextlib.contextmanager
def progress(stages: Sequence[str], quiet: bool = False) -> Iterator[StageBar]:
    """A :class:`StageBar` for the block (closed, and gone from the terminal, when it ends)."""
    bar = StageBar(stages, quiet)
    try:
        yield bar
    finally:
        bar.close()
