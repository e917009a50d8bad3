"""Measurements behind docs/benchmarks-first-run.md (not a test: run by hand).

.venv/bin/python tests/cli/measure_first_run.py compile [DWELL ARGS ...]
    runs ``dwell DWELL ARGS`` in this process under a listener of numba's compile events
    and prints the CPU in all, the atlas build's share, every top-level compile (CPU,
    wall, kernel, signature) and every function compiled, callees and numpy's own
    implementations included (inclusive CPU); point NUMBA_CACHE_DIR at an empty folder for a
    first run.
.venv/bin/python tests/cli/measure_first_run.py session COMMAND [ARGS ...]
    runs COMMAND in a session of its own and prints its wall time and the CPU of every
    process of that session, polled from /proc every 0.1 s: the build's forkserver and
    pool workers included, which /usr/bin/time does not count (nobody waits for the
    forkserver, so their times never reach the command's own accounting).
"""

import os
import resource
import subprocess
import sys
import time


def compile_split(argv):
    from numba.core import event

    compiles = []
    every: dict[str, float] = {}  # CPU per compiled function, callees (numpy's too) included

    class Compiles(event.Listener):
        def __init__(self):
            self.depth, self.start, self.nested = 0, (0.0, 0.0), []

        def on_start(self, ev):
            self.depth += 1
            self.nested.append(time.process_time())
            if self.depth == 1:  # a kernel's callees compile inside its event: counted once
                self.start = (time.process_time(), time.perf_counter())

        def on_end(self, ev):
            self.depth -= 1
            f = ev.data["dispatcher"].py_func
            name = f"{f.__module__}.{f.__qualname__}"
            every[name] = every.get(name, 0.0) + time.process_time() - self.nested.pop()
            if self.depth == 0:
                cpu, wall = time.process_time() - self.start[0], time.perf_counter() - self.start[1]
                compiles.append((cpu, wall, name, str(ev.data["args"])))

    event.register("numba:compile", Compiles())
    import atlas.build
    from cli.main import main

    build, real_build = {}, atlas.build.build_atlas

    def timed_build(*args, **kwargs):
        cpu, done = time.process_time(), len(compiles)
        try:
            return real_build(*args, **kwargs)
        finally:
            build["cpu"] = time.process_time() - cpu
            build["compiling"] = sum(c[0] for c in compiles[done:])

    atlas.build.build_atlas = timed_build  # dwell demo imports it when it runs
    cpu, wall = time.process_time(), time.perf_counter()
    try:
        main(argv)
    except SystemExit:
        pass
    out = sys.stderr
    print(
        "CPU %.1f s, wall %.1f s; compiling %.1f s of CPU in %d compiles; the atlas build %.1f s of CPU, "
        "%.1f s of it compiling"
        % (
            time.process_time() - cpu,
            time.perf_counter() - wall,
            sum(c[0] for c in compiles),
            len(compiles),
            build.get("cpu", 0.0),
            build.get("compiling", 0.0),
        ),
        file=out,
    )
    for c in sorted(compiles, key=lambda c: -c[0]):
        print("  %6.2f %6.2f  %s  %s" % (c[0], c[1], c[2], c[3][:160]), file=out)
    print("every compiled function, its callees included (CPU s; numpy's own functions too):", file=out)
    for name, cpu in sorted(every.items(), key=lambda kv: -kv[1])[:30]:
        print("  %6.2f  %s" % (cpu, name), file=out)


def session_cpu(argv):
    ticks = os.sysconf("SC_CLK_TCK")
    wall = time.perf_counter()
    child = subprocess.Popen(argv, start_new_session=True)
    seen = {}
    while child.poll() is None:
        for pid in os.listdir("/proc"):
            if not pid.isdigit():
                continue
            try:
                with open(f"/proc/{pid}/stat") as f:
                    stat = f.read()
            except OSError:
                continue
            fields = stat[stat.rindex(")") + 2 :].split()
            if int(fields[3]) == child.pid:  # its session
                seen[int(pid)] = (int(fields[11]) + int(fields[12])) / ticks
        time.sleep(0.1)
    wall = time.perf_counter() - wall
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    own = usage.ru_utime + usage.ru_stime  # the command and the processes it waited for
    # the polled sum counts every process once, waited for or not (to within a poll's 0.1 s);
    # the command's own accounting also catches processes too short-lived to be polled
    polled = sum(seen.values())
    others = polled - seen.get(child.pid, 0.0)
    print(
        "wall %.1f s, CPU %.1f s (the command and what it waited for %.1f s; %d other processes %.1f s), load %.1f"
        % (wall, max(own, polled), own, len(seen) - 1, others, os.getloadavg()[0]),
        file=sys.stderr,
    )
    return child.returncode


if __name__ == "__main__":
    if len(sys.argv) < 2 or sys.argv[1] not in ("compile", "session"):
        sys.exit(__doc__)
    if sys.argv[1] == "compile":
        compile_split(sys.argv[2:])
    else:
        sys.exit(session_cpu(sys.argv[2:]))
