"""
The replay's output bag: its connections, the copies of the inputs and the outputs' bytes.

One replay writes about as many messages as it reads (the inputs copied across, the outputs
at ``publish_rate``), and with rosbags' pure-Python mcap writer that is a third of its time.
:class:`OutputBag` does the writing; where it runs is the driver's choice:

- :class:`OutputBag` itself, in the replay's process: each input is copied as it is read
  (:meth:`OutputBag.copy`) and each output written as it is emitted (:meth:`OutputBag.write`).
- :class:`BackgroundWriter`: the same :class:`OutputBag` in a second process, fed in batches
  through a pipe while the first runs the pipeline. The second process reads the input bag's
  raw messages itself, to copy them, and places each output after the input it followed in the
  first process: the very sequence of writes of the one-process run, so the same bytes
  (test_replay compares the two). On a machine with a second core the writing then costs the
  pipeline nothing but the batching.

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
from typing import Any, Callable, Iterable, Iterator, Mapping

from vessel_kinematics.tools import bags
from vessel_kinematics.tools.bags import BagWriter

__all__ = ['BackgroundWriter', 'background_available', 'BATCH', 'OutputBag', 'WriterFailed']

#: Outputs sent to the second process per batch (about 100 kB of messages).
BATCH = 256


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
            self._copies: dict[int, Any] = {}
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
                self._copies[id(connection)] = target
        except BaseException:
            self.writer.close()
            raise

    @property
    def copies(self) -> bool:
        """Return True when any input connection is copied."""
        return bool(self._copies)

    def copy(self, connection: Any, log_ns: int, raw: Any) -> None:
        """Copy one input message (its raw bytes) when its connection is copied."""
        target = self._copies.get(id(connection))
        if target is None:
            return
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


#: An output on its way to the second process: (topic, log ns, CDR bytes, the number of input
#: messages read before it, the type of a topic the outputs lack or None).
_Item = tuple[str, int, bytes, int, 'str | None']


def background_available() -> bool:
    """
    Return True where a second process can write the bag.

    That is where ``fork`` exists (POSIX), this process runs no other thread (forking a
    threaded process can leave a lock held forever) and is not itself a daemon process.
    """
    return ('fork' in multiprocessing.get_all_start_methods()
            and threading.active_count() == 1
            and not multiprocessing.current_process().daemon)


class BackgroundWriter:
    """
    :class:`OutputBag` in a second process (``fork``), fed in batches of :data:`BATCH`.

    ``open_bag()`` is called in the second process and returns the :class:`OutputBag` and the
    input bag's raw messages ``(connection, log ns, raw)`` in the order the first process reads
    them (the connections those of the same reader, so :meth:`OutputBag.copy` knows them).
    The first process calls :meth:`tick` for every input message it reads and :meth:`write`
    for every output; :meth:`finish` waits for the bag and returns (inputs copied, not copied
    by topic); :meth:`abort` stops the second process.
    """

    def __init__(self, open_bag: Callable[[], tuple[OutputBag, Iterator[tuple[Any, int, Any]]]]
                 ) -> None:
        receive, self._send = multiprocessing.Pipe(duplex=False)
        self._results, results = multiprocessing.Pipe(duplex=False)
        context = multiprocessing.get_context('fork')
        self._process = context.Process(
            target=_serve, args=(open_bag, receive, results, (self._send, self._results)),
            name='replay-writer', daemon=True)
        self._process.start()
        receive.close()
        results.close()
        #: Input messages read so far by the first process.
        self.position = 0
        self._batch: list[_Item] = []

    def tick(self, *_: object) -> None:
        """Count one input message read (called with it, as ``on_raw``)."""
        self.position += 1

    def write(self, topic: str, at_ns: int, data: bytes, msgtype: str | None = None) -> None:
        """Queue one output, written after the input messages read so far."""
        self._batch.append((topic, at_ns, data, self.position, msgtype))
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

    def finish(self) -> tuple[int, Counter]:
        """Send what is queued, wait for the bag to be complete; return the copy counts."""
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
        return result[1], Counter(result[2])

    def abort(self) -> None:
        """Stop the second process (the bag is left unfinished; the caller removes it)."""
        if self._process.is_alive():
            self._process.terminate()
        self._process.join()
        self._send.close()
        self._results.close()


def _serve(open_bag: Callable[[], tuple[OutputBag, Iterator[tuple[Any, int, Any]]]],
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
        out, raws = open_bag()
        try:
            copying = out.copies
            position = 0
            while (batch := receive.recv()) is not None:
                for topic, at_ns, data, after, msgtype in batch:
                    while copying and position < after:   # the inputs read before this output
                        out.copy(*next(raws))
                        position += 1
                    out.write(topic, at_ns, data, msgtype)
            if copying:
                for message in raws:
                    out.copy(*message)
        finally:
            out.close()
        results.send(('ok', out.copied, dict(out.uncopied)))
    except BaseException as error:  # noqa: B902 - every failure goes back as its one line
        results.send(('error', _line(error)))
