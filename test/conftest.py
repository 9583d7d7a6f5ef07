"""Test-wide set-up: every DDS participant of this test run stays on this machine, on a domain of
its own, so parallel runs (or a robot on the same network) never see our topics."""
import os
import signal

# Tests send Ctrl-C and hangups to the processes they start, as a terminal does to a foreground job. A run started in
# the background (``./run test &`` in a script) has SIGINT ignored, one under nohup SIGHUP, and every process it starts
# inherits that (and keeps it: a signal ignored at start stays ignored): those tests would see their signal ignored.
# The default handlers again (each child then gets the signal's default at exec).
if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
if signal.getsignal(signal.SIGHUP) == signal.SIG_IGN:
    signal.signal(signal.SIGHUP, signal.SIG_DFL)

os.environ['ROS_DOMAIN_ID'] = str(100 + os.getpid() % 100)
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('RCUTILS_LOGGING_BUFFERED_STREAM', '1')

# As the node and the command line do at start (see pipeline.limit_blas_threads).
from plane_validation.app.pipeline import limit_blas_threads  # noqa: E402

limit_blas_threads()


def pytest_sessionstart(session):
    """Compile the kernels on every core before the first test needs them: a fresh clone's cache is cold, and a
    compile in one process takes most of two minutes. Write the package's bytecode too (with
    PYTHONDONTWRITEBYTECODE set, as on some machines, nothing else does): each of the many Python processes the
    tests start then loads it instead of compiling the package's source again (about 0.5 s of CPU a process)."""
    if hasattr(session.config, 'workerinput'):  # a pytest-xdist worker: its controller did both
        return
    import compileall
    from pathlib import Path

    import plane_validation
    from plane_validation.core.kernels import warm
    compileall.compile_dir(Path(plane_validation.__file__).parent, quiet=1)
    warm(jobs=os.cpu_count() or 1)
