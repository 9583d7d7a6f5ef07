"""Helpers for tests that start processes."""
from __future__ import annotations

import os
import time


def session_ended(pgid: int, timeout: float = 10.0) -> bool:
    """Whether the process group ``pgid`` (a process started with start_new_session: its session) holds no process
    any more within ``timeout`` seconds: nothing it started was left running."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.1)
    return False
