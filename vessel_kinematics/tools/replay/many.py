"""
Many bags at once: a directory of bags, or several inputs, one output each and one table.

:func:`run_many` replays each bag of :func:`find_bags` into ``OUTPUT/<name>`` with the single-bag
rules (:func:`~.run.run`), ``jobs`` at a time in separate processes (spawned: nothing of this
process is shared), and returns a :class:`BagRow` per bag: its numbers, or its one-line error
(one bag's failure is its row, never the run's). :func:`rows_table` prints them.
"""

from __future__ import annotations

from dataclasses import dataclass
import datetime
import os
from pathlib import Path
import sys
import time
from typing import Any, Mapping, Sequence

from vessel_kinematics import marine
from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.tools.replay.bag_output import check_paths
from vessel_kinematics.tools.replay.errors import error_line, ReplayError
from vessel_kinematics.tools.replay.run import run

__all__ = ['BAG_FILE_TYPES', 'BagRow', 'default_jobs', 'find_bags', 'is_bag', 'is_many',
           'output_name', 'rows_table', 'run_many']


def default_jobs() -> int:
    """Return the bags to replay at a time by default: the cores this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:          # not Linux
        return max(1, os.cpu_count() or 1)


#: Files taken as bags in a directory of bags (each rosbag2 bag directory is taken too).
BAG_FILE_TYPES = ('.bag', '.mcap')


def is_bag(path: Path) -> bool:
    """Return True for one bag: a rosbag2 directory (``metadata.yaml``) or a bag file."""
    if path.is_dir():
        return (path / 'metadata.yaml').is_file()
    return path.is_file()


def is_many(inputs: Sequence[str | Path]) -> bool:
    """Return True when ``inputs`` are several, or one directory of bags (not a bag itself)."""
    return len(inputs) > 1 or (Path(inputs[0]).is_dir() and not is_bag(Path(inputs[0])))


def _taken(entry: Path) -> bool:
    """Return True for a directory entry replayed: a bag, or a marine log (by content)."""
    if entry.is_dir():
        return is_bag(entry)
    return entry.is_file() and (entry.suffix in BAG_FILE_TYPES or marine.is_marine_log(entry))


def find_bags(inputs: Sequence[str | Path],
              skipped: list[Path] | None = None) -> list[Path]:
    """
    Return the bags of ``inputs``, in order: each bag, and the bags in each directory of bags.

    In a directory that is not a bag itself, every rosbag2 bag directory, every
    :data:`BAG_FILE_TYPES` file and every marine log (NMEA 0183, an NMEA 2000 capture: by
    content) directly in it is a bag (sorted by name; hidden entries, such as a replay's
    staging directories, are skipped); the other entries go to ``skipped`` when given. A path
    that does not exist stays in the list, for its row to say so. Raises :class:`ReplayError`
    for a directory without bags.
    """
    bags: list[Path] = []
    for given in map(Path, inputs):
        if not given.is_dir() or is_bag(given):
            bags.append(given)
            continue
        found: list[Path] = []
        others: list[Path] = []
        for entry in sorted(given.iterdir()):
            if not entry.name.startswith('.'):
                (found if _taken(entry) else others).append(entry)
        if not found:
            raise ReplayError(f'{given} is neither a bag nor a directory of bags (rosbag2 '
                              f'directories, {", ".join(BAG_FILE_TYPES)} files, marine logs)')
        bags.extend(found)
        if skipped is not None:
            skipped.extend(others)
    return bags


def output_name(bag: Path) -> str:
    """Return the name of a bag's output in the output directory: its name without suffix."""
    return bag.name if bag.is_dir() else bag.stem


@dataclass
class BagRow:
    """One row of the table of a many-bag replay: a bag's numbers, or its error."""

    name: str
    input_path: Path
    output_path: Path
    duration_s: float = 0.0
    messages_in: int = 0
    messages_out: int = 0
    rejected: int = 0
    distance_m: float = 0.0
    wall_time_s: float = 0.0
    error: str | None = None

    @property
    def ok(self) -> bool:
        """Return True when the bag was replayed."""
        return self.error is None


def _replay_one(task: tuple[str, Path, Path, NavigatorParams, Any, bool, bool, bool,
                            datetime.date | None]) -> BagRow:
    """Replay one bag of a many-bag run (in a worker process); never raises but interrupts."""
    name, source, target, params, remaps, copy_inputs, overwrite, by_stamp, date = task
    row = BagRow(name, source, target)
    start = time.monotonic()
    try:
        summary = run(source, target, params, remaps, copy_inputs=copy_inputs, progress=False,
                      overwrite=overwrite, accuracy=False, by_stamp=by_stamp, date=date)
    except Exception as error:  # noqa: B902 - one bag's failure is its row, never the run's
        row.error = error_line(error)
    else:
        row.duration_s = summary.duration_s
        row.messages_in = sum(summary.messages_in.values())
        row.messages_out = sum(summary.messages_out.values())
        row.rejected = sum(summary.rejected.values())
        row.distance_m = summary.distance_m
    row.wall_time_s = time.monotonic() - start
    return row


def run_many(inputs: Sequence[str | Path], output: str | Path,
             params: NavigatorParams | None = None,
             remaps: Sequence[str] | Mapping[str, str] | None = None, *, jobs: int = 1,
             copy_inputs: bool = True, overwrite: bool = False,
             by_stamp: bool = False, date: datetime.date | None = None) -> list[BagRow]:
    """
    Replay every bag of ``inputs`` (:func:`find_bags`) into ``output``/<name> (:func:`run`).

    ``output`` is a directory (made if missing; it must not be, lie inside or contain an
    input); each bag's output follows :func:`run`'s rules (refused if it exists unless
    ``overwrite``, written in a hidden sibling and renamed when complete). ``jobs`` > 1 replays
    that many bags at a time in separate processes (spawned: nothing of this process is
    shared). A bag that fails is a row with its one-line error; the others go on. Returns the
    rows in input order. Raises :class:`ReplayError` before any replay for unusable
    ``inputs``/``output``: no bags, two bags of one output name, an output that is a file. The
    entries of a directory that are neither bags nor marine logs are skipped, named in one
    warning on stderr.
    """
    params = params if params is not None else NavigatorParams()
    skipped: list[Path] = []
    bags = find_bags(inputs, skipped)
    if skipped:
        print('replay: warning: skipped, neither a bag nor a marine log: '
              + ', '.join(str(p) + ('/' if p.is_dir() else '') for p in skipped),
              file=sys.stderr)
    names = [output_name(bag) for bag in bags]
    seen: dict[str, Path] = {}
    for name, bag in zip(names, bags):
        if name in seen:
            raise ReplayError(f'{seen[name]} and {bag} would both write {Path(output) / name}')
        seen[name] = bag
    check_paths([*inputs, *bags], output)
    out = Path(os.path.abspath(output))
    if out.is_symlink() or (out.exists() and not out.is_dir()):
        raise ReplayError(f'output {output} exists and is not a directory')
    try:
        out.mkdir(exist_ok=True)
    except OSError as error:
        raise ReplayError(f'cannot make the output directory {output}: '
                          f'{error.strerror}') from error
    tasks = [(name, bag, out / name, params, remaps, copy_inputs, overwrite, by_stamp, date)
             for name, bag in zip(names, bags)]
    if jobs <= 1 or len(tasks) == 1:
        return [_replay_one(task) for task in tasks]
    import concurrent.futures
    import multiprocessing
    context = multiprocessing.get_context('spawn')
    rows: list[BagRow | None] = [None] * len(tasks)
    with concurrent.futures.ProcessPoolExecutor(min(jobs, len(tasks)),
                                                mp_context=context) as pool:
        futures = {pool.submit(_replay_one, task): i for i, task in enumerate(tasks)}
        try:
            for future in concurrent.futures.as_completed(futures):
                i = futures[future]
                try:
                    rows[i] = future.result()
                except Exception as error:  # noqa: B902 - e.g. a worker process that died
                    name, source, target = tasks[i][:3]
                    rows[i] = BagRow(name, source, target, error=error_line(error))
        except BaseException:       # interrupted or stopped: start no other bag
            pool.shutdown(wait=True, cancel_futures=True)
            raise
    return [row for row in rows if row is not None]


def rows_table(rows: Sequence[BagRow]) -> str:
    """Return the summary table of a many-bag replay: one row per bag, then the totals."""
    header = ('bag', 'bag time s', 'in', 'out', 'rejected', 'distance m', 'wall s', 'status')
    lines = [[row.name, f'{row.duration_s:.1f}', str(row.messages_in), str(row.messages_out),
              str(row.rejected), f'{row.distance_m:.1f}', f'{row.wall_time_s:.1f}',
              'ok' if row.ok else f'error: {row.error}'] for row in rows]
    failed = sum(not row.ok for row in rows)
    lines.append(['total', f'{sum(r.duration_s for r in rows):.1f}',
                  str(sum(r.messages_in for r in rows)), str(sum(r.messages_out for r in rows)),
                  str(sum(r.rejected for r in rows)), f'{sum(r.distance_m for r in rows):.1f}',
                  f'{sum(r.wall_time_s for r in rows):.1f}',
                  f'{len(rows) - failed} ok, {failed} failed'])
    widths = [max(len(cells[i]) for cells in [list(header), *lines[:-1], lines[-1]])
              for i in range(len(header) - 1)]

    def fmt(cells: Sequence[str]) -> str:
        left = cells[0].ljust(widths[0])
        middle = '  '.join(c.rjust(w) for c, w in zip(cells[1:-1], widths[1:]))
        return f'{left}  {middle}  {cells[-1]}'

    return '\n'.join([fmt(header)] + [fmt(cells) for cells in lines])
