"""
The replay's output: a new mcap bag, written in a hidden staging directory, placed when done.

:class:`OutputBag` holds the navigator's topics (their types and QoS from the interface table)
and the copies of the input's connections (the QoS they were recorded with, ROS 1 payloads
converted to CDR); :meth:`OutputBag.write` takes an :class:`~vessel_kinematics.ros.pipeline.
Emission`, :meth:`OutputBag.copy` each input message as it is read. Nothing is logged before
the input's first message: the output spans the input's time, as ``ros2 bag play`` reads it.

Nothing is lost or half-written: an output that is, contains or lies inside an input is refused
before anything is opened (:func:`check_paths`); ``--overwrite`` replaces only a rosbag2 bag
directory (:func:`is_bag_directory`); the bag is written in a hidden sibling directory
(:func:`staging_path`) and renamed into place (:func:`place`) only once complete, so a failure
or an interrupt leaves no output and any previous output untouched.
"""

from __future__ import annotations

from collections import Counter
import os
from pathlib import Path
import shutil
import stat
from typing import Any, Mapping, Sequence

from vessel_kinematics.ros.pipeline import Emission
from vessel_kinematics.tools import bags
from vessel_kinematics.tools.bags import BagWriter
from vessel_kinematics.tools.replay.bag_input import BagInput, TF_STATIC_TOPIC, TYPE_RENAMES
from vessel_kinematics.tools.replay.errors import ReplayError

__all__ = ['BAG_FILE_SUFFIXES', 'check_paths', 'is_bag_directory', 'OutputBag', 'place',
           'prepare_output', 'remove_stale', 'staging_path', 'WriterFailed']

#: The files a rosbag2 bag directory may hold, besides ``metadata.yaml``: what ``--overwrite``
#: accepts to remove (mcap, sqlite3 and its journal files, zstd-compressed files).
BAG_FILE_SUFFIXES = ('.mcap', '.db3', '.db3-shm', '.db3-wal', '.db3-journal', '.zstd')


class WriterFailed(Exception):
    """The output bag could not be written (its one-line reason)."""


class OutputBag:
    """
    A new mcap bag at ``path``: the navigator's topics of ``outputs`` and the copied inputs.

    ``copy_inputs``: every connection of ``bag`` is copied but the navigator's own topics,
    which the replay writes anew (the input's ``/tf_static`` is copied: it comes from other
    publishers, a URDF's robot_state_publisher, and a tf2 listener merges every message).
    The copies offer the QoS they were recorded with. The connections are made busiest first:
    rosbags' ``Writer.write`` finds a message's connection by a search of its list.
    """

    def __init__(self, path: Path, bag: BagInput, outputs: Mapping[str, str],
                 copy_inputs: bool) -> None:
        self.writer = BagWriter(path).open()
        self._to_cdr = bag.to_cdr if bag.is_ros1 else None
        #: Inputs copied; not copied (a ROS 1 payload not convertible to CDR), by topic.
        self.copied = 0
        self.uncopied: Counter = Counter()
        #: The input's topics not copied because the replay writes them.
        self.skipped: set[str] = set()
        self._copies: dict[int, tuple[Any, Any]] = {}
        self._outputs: dict[str, Any] = {}
        #: The input's first log time (None until the first message is read) and the
        #: emissions sent before it, which are logged at that time.
        self._start_ns: int | None = None
        self._early: list[Emission] = []
        try:
            if copy_inputs:
                self._add_copies(bag, outputs)
            for topic, msgtype in outputs.items():
                self._outputs[topic] = self._add_output(topic, msgtype)
        except BaseException:
            self.writer.close()
            raise

    def _add_copies(self, bag: BagInput, outputs: Mapping[str, str]) -> None:
        by_key: dict[tuple[str, str], Any] = {}
        for connection in sorted(bag.reader.connections, key=lambda c: -c.msgcount):
            if connection.topic in outputs and connection.topic != TF_STATIC_TOPIC:
                self.skipped.add(connection.topic)
                continue
            msgtype = TYPE_RENAMES.get(connection.msgtype, connection.msgtype)
            store = bag.cdr_store if msgtype in bag.cdr_store.fielddefs else bags.jazzy()
            key = (connection.topic, msgtype)
            if key not in by_key:
                by_key[key] = self.writer.add_connection(
                    connection.topic, msgtype, typestore=store,
                    offered_qos_profiles=bags.recorded_qos(connection))
            self._copies[connection.id] = (by_key[key], connection)

    def _add_output(self, topic: str, msgtype: str) -> Any:
        try:
            return self.writer.add_connection(topic, msgtype)
        except bags.BagError:           # a copied input of the same topic, type and QoS
            for target, connection in self._copies.values():
                if connection.topic == topic:
                    return target
            raise

    def copy(self, connection: Any, log_ns: int, raw: Any) -> None:
        """
        Take one input message as it is read: copy it (its bytes) when its connection is.

        The first one's log time is the output's start: what was emitted before is logged then.
        """
        if self._start_ns is None:
            self._start_ns = log_ns
            for emission in self._early:
                self.write(emission)
            self._early.clear()
        copied = self._copies.get(connection.id)
        if copied is None:
            return
        target, connection = copied
        if self._to_cdr is not None:
            try:
                raw = self._to_cdr(raw, connection.msgtype)
            except Exception:  # noqa: B902 - a garbage ROS 1 payload: not copied
                self.uncopied[connection.topic] += 1
                return
        self._write(target, log_ns, raw)
        self.copied += 1

    def write(self, emission: Emission) -> None:
        """
        Write one emission of the pipeline at its stamp, never before the input's first message.

        An earlier stamp is logged at the input's first log time: the statics of
        :meth:`~vessel_kinematics.ros.pipeline.Pipeline.start` are stamped 0, and a sensor's
        header stamp precedes its log time. Until that time is known (the first :meth:`copy`)
        emissions are held.
        """
        if self._start_ns is None:
            self._early.append(emission)
            return
        self._write(self._outputs[emission.topic], max(emission.stamp_ns, self._start_ns),
                    emission.cdr)

    def _write(self, connection: Any, at_ns: int, data: Any) -> None:
        try:
            self.writer.write(connection, at_ns, data)
        except (OSError, bags.BagError) as error:   # a full disk, a lost file system
            raise WriterFailed(_line(error)) from error

    def close(self) -> None:
        """Finish the bag (its summary and ``metadata.yaml``)."""
        try:
            self.writer.close()
        except (OSError, bags.BagError) as error:
            raise WriterFailed(_line(error)) from error


def _line(error: BaseException) -> str:
    """Return an error's first line (its type's name when it has no text)."""
    text = str(error)
    return text.splitlines()[0] if text else type(error).__name__


#: What a path that is neither a file nor a directory is, by its stat mode.
_KINDS = ((stat.S_ISFIFO, 'a FIFO'), (stat.S_ISCHR, 'a character device'),
          (stat.S_ISBLK, 'a block device'), (stat.S_ISSOCK, 'a socket'))


def _check_kind(path: Path) -> None:
    """Refuse an input that is (or a bag directory holding) a FIFO, a device or a socket."""
    try:
        mode = path.stat().st_mode
    except OSError:
        return                                  # the reader says what is wrong with it
    entries = [path]
    if stat.S_ISDIR(mode):
        try:
            entries = sorted(path.iterdir())[:10_000]
        except OSError:
            return
    for entry in entries:
        try:
            entry_mode = entry.stat().st_mode
        except OSError:
            continue
        for test, kind in _KINDS:
            if test(entry_mode):
                raise ReplayError(f'input {entry} is {kind}, not a bag file: refusing to read '
                                  'it (it could block for ever)')


def check_paths(inputs: Sequence[str | Path], output: str | Path,
                plot: str | Path | None = None) -> None:
    """
    Refuse an output (or plot) that would overwrite or nest with an input; before any I/O.

    Paths are compared as real paths (symlinks resolved, also through a not yet existing
    tail): the output must not be an input, lie inside one, or contain one. An input that is a
    FIFO, a device or a socket (or a directory holding one) is refused too: reading it could
    block for ever. The plot's directory must exist and be writable (none is made), and the
    plot must not be a directory or write into the input or the output. Raises
    :class:`ReplayError`.
    """
    out = Path(os.path.realpath(output))
    figure = None if plot is None else Path(os.path.realpath(plot))
    for given in inputs:
        _check_kind(Path(given))
        source = Path(os.path.realpath(given))
        if out == source:
            raise ReplayError(f'output {output} is the input {given}: refusing to touch it')
        if source in out.parents:
            raise ReplayError(f'output {output} is inside the input {given}: refusing')
        if out in source.parents:
            raise ReplayError(f'output {output} contains the input {given}: refusing')
        if figure is not None and (figure == source or source in figure.parents):
            raise ReplayError(f'plot {plot} would write into the input {given}: refusing')
    if figure is not None and plot is not None:
        if figure == out or out in figure.parents:
            raise ReplayError(f'plot {plot} would write into the output {output}: refusing')
        _check_plot(Path(os.path.abspath(plot)))


def _check_plot(figure: Path) -> None:
    """Refuse a plot path whose directory is missing or not writable, or that is one."""
    if figure.is_dir():
        raise ReplayError(f'plot {figure} is a directory (give a file name, e.g. run.png)')
    parent = figure.parent
    if not parent.is_dir():
        raise ReplayError(f'plot directory {parent} does not exist')
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ReplayError(f'plot directory {parent} is not writable')


def is_bag_directory(path: Path) -> bool:
    """
    Return True for a rosbag2 bag directory: ``metadata.yaml`` and only bag files in it.

    Bag files are regular files named with :data:`BAG_FILE_SUFFIXES`; a symlink (to the
    directory or in it) or any other entry makes it something else, which ``--overwrite``
    does not remove.
    """
    if path.is_symlink() or not path.is_dir():
        return False
    names = set()
    for entry in path.iterdir():
        if entry.is_symlink() or not entry.is_file():
            return False
        if entry.name != 'metadata.yaml' and not entry.name.endswith(BAG_FILE_SUFFIXES):
            return False
        names.add(entry.name)
    return 'metadata.yaml' in names


def prepare_output(output: Path, overwrite: bool) -> bool:
    """Check that ``output`` can be written; return True when a previous output is replaced."""
    if output.exists() or output.is_symlink():
        if not overwrite:
            raise ReplayError(f'output {output} exists already (use --overwrite to replace it)')
        if not is_bag_directory(output):
            raise ReplayError(f'output {output} exists and is not a rosbag2 bag (metadata.yaml '
                              'and bag files only): not replacing it')
        return True
    parent = output.parent
    if not parent.is_dir():
        raise ReplayError(f'output directory {parent} does not exist')
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ReplayError(f'output directory {parent} is not writable')
    return False


def staging_path(output: Path) -> Path:
    """Return the hidden sibling directory a replay writes ``output`` in before moving it."""
    return output.parent / f'.{output.name}.replay-{os.getpid()}'


def _alive(pid: int) -> bool:
    """Return True when process ``pid`` exists (another user's counts as alive)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return True
    return True


def remove_stale(output: Path) -> list[str]:
    """
    Remove what a killed replay of ``output`` left beside it; return one line per thing done.

    A replay killed outright (SIGKILL, a power loss) cannot clean up: its staging directory
    ``.OUT.replay-PID`` stays, and a kill between the two renames of an ``--overwrite`` leaves
    the previous output as ``.OUT.replaced-PID``. Those of a process no longer alive are
    removed (staging) or renamed back (a previous output, when ``output`` is missing).
    """
    lines: list[str] = []
    prefix = f'.{output.name}.'
    try:
        entries = list(output.parent.iterdir())
    except OSError:
        return lines
    for entry in sorted(entries):
        name = entry.name
        kind, _, pid_text = name[len(prefix):].rpartition('-')
        if not name.startswith(prefix) or kind not in ('replay', 'replaced') \
                or not pid_text.isdigit() or _alive(int(pid_text)) or entry.is_symlink():
            continue
        if kind == 'replaced' and is_bag_directory(entry) and not output.exists():
            os.rename(entry, output)
            lines.append(f'restored {output} from {name}, left by a replay that was killed '
                         f'(process {pid_text} is gone)')
        elif kind == 'replay' and entry.is_dir():
            shutil.rmtree(entry, ignore_errors=True)
            lines.append(f'removed {name}/, the staging directory of a replay that was killed '
                         f'(process {pid_text} is gone)')
    return lines


def place(written: Path, output: Path, replace: bool) -> None:
    """Move the finished bag ``written`` to ``output`` (replacing a previous output)."""
    if not replace:
        if output.exists() or output.is_symlink():
            raise ReplayError(f'output {output} appeared during the replay: not replacing it')
        os.rename(written, output)
        return
    if not is_bag_directory(output):
        raise ReplayError(f'output {output} changed during the replay: not replacing it')
    previous = output.parent / f'.{output.name}.replaced-{os.getpid()}'
    os.rename(output, previous)
    try:
        os.rename(written, output)
    except BaseException:
        os.rename(previous, output)
        raise
    shutil.rmtree(previous)
