"""Start one node process that dies with its launcher (agv-launch's child wrapper).

`python -m agv_nodes.graph.child PARENT_PID [--sched-fifo N] COMMAND...` asks Linux for SIGTERM
when the thread that started it exits (prctl PR_SET_PDEATHSIG, kept across exec), optionally takes
SCHED_FIFO priority N (kept across exec and inherited by every thread, DDS's too), then execs
COMMAND (same pid). So a SIGKILLed launcher leaves no graph to cross-talk with a later one on its
ROS domain. Popen's preexec_fn is not safe once the launcher has threads; a fresh interpreter is.
"""

import ctypes
import os
import signal
import sys

PR_SET_PDEATHSIG = 1


def main(argv: list[str] | None = None) -> int:
    """Entry point; never returns when the exec succeeds."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) < 2:
        print('usage: python -m agv_nodes.graph.child PARENT_PID [--sched-fifo N] COMMAND...',
              file=sys.stderr)
        return 2
    parent, command = int(args[0]), args[1:]
    if command[:1] == ['--sched-fifo'] and len(command) > 2:
        priority, command = int(command[1]), command[2:]
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        except OSError as exc:  # EPERM without the right, EINVAL outside 1-99
            print(f'agv_nodes.graph.child: SCHED_FIFO priority {priority} refused ({exc})',
                  file=sys.stderr)
            return 2
    if sys.platform.startswith('linux'):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
        if os.getppid() != parent:  # the launcher died before the request was in place
            return 1
    os.execv(command[0], command)
    return 1  # not reached


if __name__ == '__main__':
    sys.exit(main())
