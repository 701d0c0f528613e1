"""What the python-can tests of tests/can share: python-can itself (or the skip exit when it
is missing), the check list and stopping a child process."""

import subprocess
import sys

SKIP = 77


def import_can():
    """python-can, or exit 77 (ctest's skip) naming why it cannot be imported."""
    try:
        import can
    except ImportError as error:
        print(f"SKIP: python-can (Debian: python3-can) is not importable by {sys.executable}: {error}")
        sys.exit(SKIP)
    return can


class Checks:
    def __init__(self):
        self.passed, self.failed = 0, []

    def check(self, ok, what):
        print(("PASS " if ok else "FAIL ") + what, flush=True)
        if ok:
            self.passed += 1
        else:
            self.failed.append(what)
        return ok


def stop(proc, timeout=10):
    """SIGTERM, then SIGKILL after `timeout` seconds; waits for the process."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
