"""
The replay of one bag into a new bag: :func:`run`, what the ``replay`` command does per bag.

The loop (:mod:`.loop`) sends every emission to the output bag (:mod:`.bag_output`: staged,
and placed only when complete and usable); afterwards the run is scored against the
simulator's truth when the bag holds it (:mod:`.scoring`) and drawn when asked
(:mod:`vessel_kinematics.tools.plot`).
"""

from __future__ import annotations

import datetime
import os
from pathlib import Path
import shutil
import sys
import time
from typing import Any, Mapping, Sequence

from vessel_kinematics.ros.params import NavigatorParams
from vessel_kinematics.ros.pipeline import fewer_collections
from vessel_kinematics.tools.replay import scoring
from vessel_kinematics.tools.replay.bag_input import BagInput
from vessel_kinematics.tools.replay.bag_output import (check_paths, OutputBag, place,
                                                       prepare_output, remove_stale,
                                                       staging_path, WriterFailed)
from vessel_kinematics.tools.replay.errors import one_line, ReplayError
from vessel_kinematics.tools.replay.loop import OUTPUT_TYPES, Progress, Replay, Summary

__all__ = ['run']


def run(input_path: str | Path, output_path: str | Path,
        params: NavigatorParams | None = None,
        remaps: Sequence[str] | Mapping[str, str] | None = None, *,
        copy_inputs: bool = True, plot: str | Path | None = None,
        progress: bool | None = None, overwrite: bool = False,
        accuracy: bool = True, by_stamp: bool = False,
        date: datetime.date | None = None) -> Summary:
    """
    Replay the bag ``input_path`` through the navigator's pipeline into ``output_path`` (mcap).

    ``params`` default to the navigator's defaults; ``remaps`` map input names to bag topics
    (``['fix:=/gps/fix']`` or ``{'fix': '/gps/fix'}``). ``plot`` writes a figure of the run
    (:func:`vessel_kinematics.tools.plot.plot`). ``progress`` None = a bar when stderr is a
    terminal. The messages go to the pipeline in log-time order, each arriving at its log
    time, as the node received them; ``by_stamp`` merges them by header stamp instead
    (:class:`~.bag_input.StampOrder`). ``date``: the date of a marine log of times of day
    without one (:func:`~vessel_kinematics.marine.open_log`). When the input holds simulator truth
    (``/truth/odometry``) and ``accuracy`` is true, the summary carries the accuracy table
    (:mod:`.scoring`: the fused run beside a dead-reckoning-only replay made in memory). A plot
    that cannot be written once the output is, is one warning on stderr (``summary.plot``
    None). What a killed replay of the same output left (:func:`~.bag_output.remove_stale`) is
    removed first, with one line on stderr. Raises
    :class:`ReplayError` for unusable input or options, and for a run without input messages
    or whose every input was rejected; the output is then not written (see
    :mod:`.bag_output`).
    """
    params = params if params is not None else NavigatorParams()
    check_paths([input_path], output_path, plot)
    wall_start = time.monotonic()
    summary = Summary(input_path=Path(input_path), output_path=Path(output_path))
    # Absolute (symlinks kept), so that '.' or 'x/..' have a name and a parent to stage in.
    output = Path(os.path.abspath(output_path))
    for line in remove_stale(output):
        print(f'replay: warning: {line}', file=sys.stderr)
    with BagInput(input_path, params, remaps, date=date) as bag:
        params = bag.params
        summary.notes += bag.notes
        replace = prepare_output(output, overwrite)
        summary.topics = dict(bag.topics)
        has_truth = bag.has_truth
        has_reference = bag.has_reference
        staging = staging_path(output)
        try:
            # Made inside the try: a stop signal just after mkdir still removes it.
            try:
                staging.mkdir()
            except OSError as error:
                raise ReplayError(f'cannot write in {output.parent}: '
                                  f'{error.strerror}') from error
            written = staging / output.name
            _write(bag, params, summary, written, copy_inputs, progress, by_stamp)
            if bag.marine:
                summary.notes += [f'{bag.reader.format}: {line}'
                                  for line in bag.reader.counts.text().splitlines()]
            place(written, output, replace)
        finally:
            shutil.rmtree(staging, ignore_errors=True)
    summary.wall_time_s = time.monotonic() - wall_start
    if has_reference and copy_inputs:
        from vessel_kinematics.tools import evaluate
        summary.reference = evaluate.reference_line(
            evaluate.load_run(output, fix_topic=summary.topics['fix']),
            fused='gnss_velocity' in summary.topics)
    if plot is None and not (accuracy and has_truth):
        return summary
    inputs_bag = None if copy_inputs else Path(input_path)
    fused = dr_run = None
    if accuracy and has_truth:
        summary.accuracy, fused, dr_run = scoring.accuracy_report(
            output, params, remaps, inputs_bag=inputs_bag)
    if plot is not None:
        summary.plot = _draw(fused if fused is not None else output, Path(plot),
                             fix_topic=summary.topics['fix'], fixes_bag=inputs_bag,
                             dead_reckoning=dr_run)
    return summary


def _draw(source: Any, plot: Path, **options: Any) -> Path | None:
    """
    Draw the run into ``plot`` (written beside it, then renamed: never half a file); return it.

    The output is written by then: a failure (a full disk) is one warning naming the plot and
    None, not an error of the run.
    """
    target = plot if plot.suffix else plot.with_name(plot.name + '.png')   # as matplotlib
    temporary = target.with_name(f'.{target.stem}.replay-{os.getpid()}{target.suffix}')
    try:
        from vessel_kinematics.tools import plot as figure   # matplotlib, only when drawing
        figure.plot(source, temporary, **options)
        os.replace(temporary, target)
    except Exception as error:  # noqa: B902 - the bag is written: the plot's failure is a warning
        cause = error.strerror if isinstance(error, OSError) and error.strerror else error
        print(f'replay: warning: plot {plot} not written: {one_line(cause)}', file=sys.stderr)
        return None
    finally:
        temporary.unlink(missing_ok=True)
    return target


def _write(bag: BagInput, params: NavigatorParams, summary: Summary, output: Path,
           copy_inputs: bool, progress: bool | None, by_stamp: bool = False) -> None:
    """Write the replay of ``bag`` as a new mcap bag at ``output`` (which must not exist)."""
    bar = Progress(bag.message_count, progress)
    try:
        out = OutputBag(output, bag, OUTPUT_TYPES, copy_inputs)
        try:
            replay = Replay(bag, params, summary, out.write, by_stamp)
            with fewer_collections():
                # Every message read passes the output, copied or not: the first one's
                # log time is the output's start.
                replay.run(out.copy, bar)
            replay.check_usable()
        finally:
            out.close()
    except WriterFailed as error:
        raise ReplayError(f'cannot write {output}: {error}') from error
    finally:
        bar.close()
    if out.skipped:
        summary.notes.append('not copied (the replay writes them): '
                             + ', '.join(sorted(out.skipped)))
    summary.messages_copied += out.copied
    if out.uncopied:
        summary.notes.append('not copied (ROS 1 payload not convertible to CDR): '
                             + ', '.join(f'{t} {n}' for t, n in sorted(out.uncopied.items())))
