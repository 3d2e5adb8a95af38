"""
The replay's output bag: its connections, the copies of the inputs and the outputs' bytes.

One replay writes about as many messages as it reads (the inputs copied across, the outputs
at ``publish_rate``), and with rosbags' pure-Python mcap writer that is a third of its time.
:class:`OutputBag` does the writing; where it runs is the driver's choice:

- :class:`OutputBag` itself, in the replay's process: each input is copied as it is read
  (:meth:`OutputBag.copy`) and each output written as it is emitted (:meth:`OutputBag.write`).
- :class:`BackgroundWriter`: the same :class:`OutputBag` in a second process, fed in batches
  through a pipe while the first runs the estimator. The first sends, in the one-process
  order, the raw inputs to copy, the outputs it built, and the emissions it leaves to the
  second process's :class:`Builder` (the replay hands over the estimator's state and the
  second process builds the outputs from it, with the same code). The second process writes
  them in that order: the very sequence of writes of the one-process run, so the same bytes
  (test_replay and test_replay_real compare the two). On a machine with a second core, the
  outputs' state, messages and writing then cost the first process a few microseconds each.

Failures are one line: the second process reports its error and the first raises it as
:class:`WriterFailed`; an interrupted replay stops the second process before the staging
directory is removed, so neither way leaves a half bag (:func:`vessel_kinematics.tools.
replay.run` writes in a staging directory).
"""

from __future__ import annotations

from collections import Counter
import multiprocessing
import multiprocessing.connection
from pathlib import Path
import threading
from typing import Any, Callable, Collection, Iterable, Mapping, Protocol

from vessel_kinematics.tools import bags
from vessel_kinematics.tools.bags import BagWriter

__all__ = ['BackgroundWriter', 'background_available', 'BATCH', 'Builder', 'Opened', 'OutputBag',
           'PIPE_CAPACITY', 'widen_pipe', 'WriterFailed']

#: Items sent to the second process per batch (about 100 kB of messages).
BATCH = 256
#: The capacity (bytes) asked of the OS for the pipe of batches: about ten batches. Linux gives
#: a pipe 64 KiB, less than one batch: the first process then waited for the second to take
#: each batch, and each for the other's every hiccup (up to ``/proc/sys/fs/pipe-max-size``, 1
#: MiB by default; where it cannot be had, the pipe keeps its size).
PIPE_CAPACITY = 1 << 20


class WriterFailed(Exception):
    """The output bag could not be written (its one-line reason)."""


class OutputBag:
    """
    A new mcap bag at ``path`` with the replay's connections: ``outputs`` and copied inputs.

    ``outputs``: {topic: type} of the navigator's topics (offered QoS from the interface
    table). ``inputs``: the input bag's connections to copy, with their type (as copied) and
    typestore, and whether the bag is ROS 1 (``to_cdr`` converts its payloads); a copied
    connection offers the QoS it was recorded with, or shares the output connection of the same
    topic, type and QoS. ``typestore``: the message definitions of the outputs.
    """

    def __init__(self, path: Path, outputs: Mapping[str, str],
                 inputs: Iterable[tuple[Any, str, Any]], typestore: Any,
                 to_cdr: Callable[[Any, str], bytes] | None) -> None:
        self.writer = BagWriter(path).open()
        self.typestore = typestore
        self.to_cdr = to_cdr
        #: Inputs copied, and not copied (a ROS 1 payload not convertible to CDR) by topic.
        self.copied = 0
        self.uncopied: Counter = Counter()
        try:
            self.connections: dict[Any, Any] = {
                topic: self.writer.add_connection(topic, msgtype, typestore=typestore)
                for topic, msgtype in outputs.items()}
            #: {input connection id: (its output connection, the input connection)}
            self._copies: dict[int, tuple[Any, Any]] = {}
            for connection, msgtype, store in inputs:
                key = (connection.topic, msgtype)
                target = self.connections.get(key)
                if target is None:
                    try:
                        target = self.writer.add_connection(
                            connection.topic, msgtype, typestore=store,
                            offered_qos_profiles=bags.recorded_qos(connection))
                    except bags.BagError:  # the same topic, type and QoS as an output's
                        if connection.topic not in self.connections:
                            raise
                        target = self.connections[connection.topic]
                    self.connections[key] = target
                self._copies[connection.id] = (target, connection)
        except BaseException:
            self.writer.close()
            raise

    @property
    def copies(self) -> bool:
        """Return True when any input connection is copied."""
        return bool(self._copies)

    def copy(self, connection: Any, log_ns: int, raw: Any) -> None:
        """Copy one input message (its raw bytes) when its connection is copied."""
        self.copy_by_id(connection.id, log_ns, raw)

    def copy_by_id(self, connection_id: int, log_ns: int, raw: Any) -> None:
        """Copy one input message of the input connection of id ``connection_id``."""
        copied = self._copies.get(connection_id)
        if copied is None:
            return
        target, connection = copied
        if self.to_cdr is not None:
            try:
                raw = self.to_cdr(raw, connection.msgtype)
            except Exception:  # noqa: B902 - a garbage ROS 1 payload: not copied
                self.uncopied[connection.topic] += 1
                return
        self._write(target, log_ns, raw)
        self.copied += 1

    def write(self, topic: str, at_ns: int, data: bytes, msgtype: str | None = None) -> None:
        """Write one output's CDR bytes; ``msgtype`` adds a topic the outputs lack (reliable)."""
        connection = self.connections.get(topic)
        if connection is None:
            if msgtype is None:
                raise WriterFailed(f'{topic}: no connection and no type to add one')
            connection = self.writer.add_connection(
                topic, msgtype, typestore=self.typestore,
                offered_qos_profiles=bags.RELIABLE_QOS)
            self.connections[topic] = connection
        self._write(connection, at_ns, data)

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


#: What goes to the second process, in the order of the one-process writes: an input to copy
#: (:data:`_COPY`, its connection's id, log ns, raw bytes), an output (:data:`_OUTPUT`, topic,
#: log ns, CDR bytes, the type of a topic the outputs lack or None) or an emission for the
#: builder (:data:`_DEFERRED`, its payload).
_Item = tuple[Any, ...]
_COPY, _OUTPUT, _DEFERRED = 0, 1, 2


class Builder(Protocol):
    """Build and write the deferred emissions in the second process (see BackgroundWriter)."""

    def build(self, payload: bytes | None, out: OutputBag) -> None:
        """Write the outputs of one emission (its payload from :meth:`BackgroundWriter.defer`)."""

    def report(self) -> Any:
        """Return what the first process learns from the outputs built (picklable)."""


#: What the second process opens: the output bag, and the builder of deferred emissions (None:
#: none are sent).
Opened = tuple[OutputBag, 'Builder | None']


def background_available() -> bool:
    """
    Return True where a second process can write the bag.

    That is where ``fork`` exists (POSIX), this process runs no other thread (forking a
    threaded process can leave a lock held forever) and is not itself a daemon process.
    """
    return ('fork' in multiprocessing.get_all_start_methods()
            and threading.active_count() == 1
            and not multiprocessing.current_process().daemon)


def widen_pipe(end: multiprocessing.connection.Connection, capacity: int) -> int:
    """
    Widen a pipe to at least ``capacity`` bytes (Linux ``F_SETPIPE_SZ``); return its capacity.

    Never narrows it. The capacity it has afterwards: at least as asked (the kernel rounds up
    to pages), or as it was where the system refuses the size; 0 where the system cannot tell
    (not Linux, or not a pipe: nothing is changed there).
    """
    try:
        import fcntl
        set_size, get_size = fcntl.F_SETPIPE_SZ, fcntl.F_GETPIPE_SZ
    except (ImportError, AttributeError):       # not Linux
        return 0
    fd = end.fileno()
    try:
        size = fcntl.fcntl(fd, get_size)
    except OSError:                             # not a pipe: nothing to widen
        return 0
    if size < capacity:
        try:
            size = fcntl.fcntl(fd, set_size, capacity)
        except OSError:                         # above the system's limit: as it was
            pass
    return size


class BackgroundWriter:
    """
    :class:`OutputBag` in a second process (``fork``), fed in batches of :data:`BATCH`.

    ``open_bag()`` is called in the second process and returns the :class:`OutputBag` and a
    :class:`Builder` or None. The first process calls :meth:`copy` for every input message it
    reads (``copied``: the ids of the connections to copy), and :meth:`write` for every
    output it built or :meth:`defer` for an emission the builder builds there (from the copy
    of the first process's objects made by the fork), in the one-process order: the second
    process writes them in that order, so the bag is the same. :meth:`finish` waits for the
    bag and returns (inputs copied, not copied by topic, the builder's report); :meth:`abort`
    stops the second process.
    """

    def __init__(self, open_bag: Callable[[], Opened], copied: Collection[int] = ()) -> None:
        receive, self._send = multiprocessing.Pipe(duplex=False)
        widen_pipe(self._send, PIPE_CAPACITY)
        self._results, results = multiprocessing.Pipe(duplex=False)
        context = multiprocessing.get_context('fork')
        self._process = context.Process(
            target=_serve, args=(open_bag, receive, results, (self._send, self._results)),
            name='replay-writer', daemon=True)
        self._process.start()
        receive.close()
        results.close()
        self._copied = frozenset(copied)
        self._batch: list[_Item] = []

    def copy(self, connection: Any, log_ns: int, raw: Any) -> None:
        """Queue an input message for copying (when its connection is copied)."""
        if connection.id in self._copied:
            self._queue((_COPY, connection.id, log_ns, bytes(raw)))

    def write(self, topic: str, at_ns: int, data: bytes, msgtype: str | None = None) -> None:
        """Queue one output."""
        self._queue((_OUTPUT, topic, at_ns, data, msgtype))

    def defer(self, payload: bytes | None) -> None:
        """Queue an emission for the builder."""
        self._queue((_DEFERRED, payload))

    def _queue(self, item: _Item) -> None:
        self._batch.append(item)
        if len(self._batch) >= BATCH:
            self._flush()

    def _flush(self) -> None:
        batch, self._batch = self._batch, []
        try:
            self._send.send(batch)
        except (BrokenPipeError, ConnectionResetError, EOFError):
            raise WriterFailed(self._failure()) from None

    def _failure(self) -> str:
        """Return the second process's reason for stopping."""
        try:
            if self._results.poll(5.0):
                result = self._results.recv()
                if result[0] == 'error':
                    return str(result[1])
        except (EOFError, OSError):
            pass
        self._process.join(1.0)
        return f'the writer process stopped (exit code {self._process.exitcode})'

    def finish(self) -> tuple[int, Counter, Any]:
        """Send what is queued, wait for the bag; return the copy counts and the report."""
        self._flush()
        try:
            self._send.send(None)
        except (BrokenPipeError, ConnectionResetError, EOFError):
            raise WriterFailed(self._failure()) from None
        try:
            result = self._results.recv()
        except EOFError:
            raise WriterFailed(self._failure()) from None
        finally:
            self._process.join()
        if result[0] == 'error':
            raise WriterFailed(str(result[1]))
        return result[1], Counter(result[2]), result[3]

    def abort(self) -> None:
        """Stop the second process (the bag is left unfinished; the caller removes it)."""
        if self._process.is_alive():
            self._process.terminate()
        self._process.join()
        self._send.close()
        self._results.close()


def _serve(open_bag: Callable[[], Opened],
           receive: multiprocessing.connection.Connection,
           results: multiprocessing.connection.Connection,
           theirs: tuple[multiprocessing.connection.Connection, ...]) -> None:
    """
    Write the batches in the one-process order and report the counts (the second process).

    ``theirs``: the first process's ends of the pipes, closed here at once, so that the first
    process ending (even killed) ends the batches here (EOF) instead of leaving a reader
    waiting on its own copy of the writing end.
    """
    for end in theirs:
        end.close()
    try:
        out, builder = open_bag()
        try:
            while (batch := receive.recv()) is not None:
                for item in batch:
                    kind = item[0]
                    if kind == _COPY:
                        out.copy_by_id(item[1], item[2], item[3])
                    elif kind == _OUTPUT:
                        out.write(item[1], item[2], item[3], item[4])
                    else:
                        assert builder is not None, 'an emission deferred without a builder'
                        builder.build(item[1], out)
        finally:
            out.close()
        results.send(('ok', out.copied, dict(out.uncopied),
                      None if builder is None else builder.report()))
    except BaseException as error:  # noqa: B902 - every failure goes back as its one line
        results.send(('error', _line(error)))
