"""What a container allows this process: its control group's CPU quota and memory limit.

A container's limits (``docker run --cpus 2 --memory 4g``, a Kubernetes pod's limits, a batch
system's job) are a Linux control group's, and neither Numba (a thread per processor it may run
on) nor ``/proc/meminfo`` (the whole machine's memory) sees them: a process that trusts those
starts a thread for every core of a 64-core node under a 2-CPU quota, and a grid that "fits" the
machine's memory is killed by the group's out-of-memory killer, with no message, instead of being
refused by :func:`clothgrid.memory.check_memory`.

Both cgroup versions are read: v2 (``cpu.max``, ``memory.max``, ``memory.current``) and v1 (the
``cpu`` and ``memory`` controllers' ``cpu.cfs_quota_us`` / ``cpu.cfs_period_us``,
``memory.limit_in_bytes`` / ``memory.usage_in_bytes``). A limit set on any ancestor of the group
binds too, so the tightest along the path from the process's group (``/proc/self/cgroup``) to
the root of the mounted hierarchy counts; in a container whose group is the root of its own view
(a cgroup namespace, or v1 with the container's group mounted at the root) the root's files are
its own. Where nothing can be read (not Linux, no cgroup file system) there is no limit.

Only the standard library is used: :mod:`clothgrid._startup` reads the CPU quota on import,
before Numba loads.
"""

from __future__ import annotations

import math
import os

__all__ = ["cpu_quota", "processors", "quota_processors", "usable_processors", "memory_headroom", "MemoryLimit"]

ROOT = "/sys/fs/cgroup"
PROC = "/proc/self/cgroup"

#: A v1 memory limit at or above this is "no limit" (the kernel writes 2^63 less a page)
_UNLIMITED = 1 << 60


def _group_dirs(controller: str, root: str = ROOT, proc: str = PROC) -> list[tuple[str, bool]]:
    """``(directory, v2)`` of this process's group for ``controller`` and of each ancestor, leaf
    first; the hierarchy roots themselves where ``/proc/self/cgroup`` cannot be read."""
    try:
        with open(proc) as f:
            lines = f.read().splitlines()
    except OSError:
        return [(root, True), (os.path.join(root, controller), False)]
    places: list[tuple[str, bool]] = []
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        _, controllers, path = parts
        if controllers == "":          # v2: the unified hierarchy (beside v1 ones under unified/)
            hybrid = not os.path.exists(os.path.join(root, "cgroup.controllers"))
            base, v2 = (os.path.join(root, "unified") if hybrid else root), True
        elif controller in controllers.split(","):
            base, v2 = os.path.join(root, controllers), False
            if not os.path.isdir(base):
                base = os.path.join(root, controller)
        else:
            continue
        path = path.strip("/")
        while True:                    # the group and each of its ancestors
            places.append((os.path.join(base, path) if path else base, v2))
            if not path:
                break
            path = os.path.dirname(path)
    return list(dict.fromkeys(places))


def _read(directory: str, name: str) -> str | None:
    try:
        with open(os.path.join(directory, name)) as f:
            return f.read().strip()
    except OSError:
        return None


def _quota_of(directory: str, v2: bool) -> float | None:
    """The CPUs one group directory allows (quota over period); None for no limit or no file."""
    try:
        if v2:
            text = _read(directory, "cpu.max")
            if text is None:
                return None
            quota, period = text.split()[:2]
            if quota == "max":
                return None
        else:
            quota, period = _read(directory, "cpu.cfs_quota_us"), _read(directory, "cpu.cfs_period_us")
            if quota is None or period is None:
                return None
        q, p = int(quota), int(period)
    except ValueError:
        return None
    return q / p if q > 0 and p > 0 else None


def cpu_quota(root: str = ROOT, proc: str = PROC) -> float | None:
    """The CPUs this process's control group may use (its CFS quota over its period: a container's
    ``--cpus``, a Kubernetes CPU limit), the least of its own and its ancestors'; None where no
    limit is set or none can be read."""
    found = [q for d, v2 in _group_dirs("cpu", root, proc) if (q := _quota_of(d, v2)) is not None]
    return min(found) if found else None


def processors() -> int:
    """The processors this process may run on (its affinity mask; all of them where the system has
    no such mask)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):          # not on Linux
        return max(1, os.cpu_count() or 1)


def quota_processors(quota: float) -> int:
    """Whole processors for a CPU quota of ``quota``: rounded up, at least one (a 1.5-CPU quota
    keeps two busy half the time)."""
    return max(1, math.ceil(quota - 1e-9))


def usable_processors() -> int:
    """The processors this process may use: :func:`processors`, at most its control group's quota
    rounded up (:func:`quota_processors`)."""
    n = processors()
    quota = cpu_quota()
    return n if quota is None else min(n, quota_processors(quota))


class MemoryLimit:
    """A control group's memory limit and what the group uses under it, in bytes.

    ``used`` is the group's working set: its usage less the page cache the kernel can drop first
    (``inactive_file``), as container runtimes count it; ``room = limit - used``.
    """

    __slots__ = ("limit", "used", "directory")

    def __init__(self, limit: int, used: int, directory: str):
        self.limit, self.used, self.directory = int(limit), max(int(used), 0), directory

    @property
    def room(self) -> int:
        return max(self.limit - self.used, 0)

    def __repr__(self) -> str:
        return f"MemoryLimit(limit={self.limit}, used={self.used}, directory={self.directory!r})"


def _stat_value(directory: str, keys: tuple[str, ...]) -> int:
    text = _read(directory, "memory.stat") or ""
    values = dict(line.split()[:2] for line in text.splitlines() if len(line.split()) >= 2)
    for key in keys:
        try:
            return int(values[key])
        except (KeyError, ValueError):
            continue
    return 0


def _memory_of(directory: str, v2: bool) -> MemoryLimit | None:
    """One group directory's memory limit and working set; None for no limit or no file."""
    try:
        if v2:
            limit_text, usage_text = _read(directory, "memory.max"), _read(directory, "memory.current")
            if limit_text is None or usage_text is None or limit_text == "max":
                return None
            inactive = _stat_value(directory, ("inactive_file",))
        else:
            limit_text, usage_text = (_read(directory, "memory.limit_in_bytes"),
                                      _read(directory, "memory.usage_in_bytes"))
            if limit_text is None or usage_text is None:
                return None
            inactive = _stat_value(directory, ("total_inactive_file", "inactive_file"))
        limit, usage = int(limit_text), int(usage_text)
    except ValueError:
        return None
    if limit <= 0 or limit >= _UNLIMITED:
        return None
    return MemoryLimit(limit, usage - inactive, directory)


def memory_headroom(root: str = ROOT, proc: str = PROC) -> MemoryLimit | None:
    """The tightest memory limit of this process's control group and its ancestors (the least
    ``room``), or None where none is set or none can be read."""
    found = [m for d, v2 in _group_dirs("memory", root, proc) if (m := _memory_of(d, v2)) is not None]
    return min(found, key=lambda m: m.room) if found else None
