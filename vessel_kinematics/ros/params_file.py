"""
The one reader of ROS 2 parameters files and ``-p NAME:=VALUE`` values, for both drivers.

The node runs it on its ``--params-file`` and ``-p`` arguments before ``rclpy.init`` (rcl then
parses the same file in C, and must meet nothing this reader refused), the replay on its own.
So a file is refused, or read, alike: with the same limits (:data:`MAX_BYTES`, :data:`MAX_DEPTH`,
:data:`MAX_KEYS`, :data:`MAX_ITEMS`, :data:`MAX_NODES`; no anchors or aliases) checked on the
parser's events before anything is composed, with rcl's rules for the node sections
(:func:`node_pattern_matches`: ``/**``, ``/**/navigator``, ``/ns/navigator``, ``navigator``;
later sections win) and with YAML 1.2's numbers, as rcl reads them: ``2e0``, ``.5`` and
``1.0e-3`` are floats (PyYAML's YAML 1.1 rules would make ``2e0`` a string). Every failure is
a :class:`~.params.ParameterError` of one line, with at most a short excerpt of the file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
import re
from typing import Any, Callable, Iterator, Mapping, Sequence

from vessel_kinematics.ros.params import excerpt, ParameterError, PARAMETERS, REMOVED
import yaml

__all__ = ['FOREIGN_PREFIXES', 'flatten', 'MAX_BYTES', 'MAX_DEPTH', 'MAX_ITEMS', 'MAX_KEYS',
           'MAX_NODES', 'node_pattern_matches', 'parse_value', 'ParamsFile', 'ParamsFileError',
           'read_params_file', 'unknown_names_line', 'without_removed']

#: Largest parameters file read (bytes): a navigator's file is a few kB; a log or a bag given
#: by mistake is refused before it is parsed.
MAX_BYTES = 1 << 20
#: Deepest nesting of mappings and sequences (the navigator's own is 4 deep: node,
#: ros__parameters, gnss, value): deeper YAML would only exhaust the recursive composer.
MAX_DEPTH = 32
#: Most mapping keys in a file (a robot's shared file of many nodes has hundreds).
MAX_KEYS = 10_000
#: Most YAML nodes (keys, values, list items, collections) in a file: what bounds the time to
#: read one within the byte limit (PyYAML takes about 50 us a node).
MAX_NODES = 50_000
#: Longest sequence (a 15x15 covariance of another node has 225 items; the navigator's lists
#: have at most 4).
MAX_ITEMS = 1024
#: Names of every rclpy node, not the navigator's (use_sim_time,
#: qos_overrides.<topic>.<entity>.<policy>, ...): the node takes them as rclpy does, the replay
#: accepts and ignores them.
FOREIGN_PREFIXES = ('use_sim_time', 'qos_overrides.', 'start_type_description_service')

_KNOWN = frozenset(p.name for p in PARAMETERS)


class _Loader(getattr(yaml, 'CSafeLoader', yaml.SafeLoader)):  # type: ignore[misc]
    """
    PyYAML's safe loader (libyaml's where built with it), with YAML 1.2's exponent floats.

    YAML 1.1 wants a dot and a signed exponent (``1.0e+3``); YAML 1.2, and rcl, take ``2e0``,
    ``1e-3`` and ``.5e2`` too, and rcl (``strtod``) ``nan`` and ``inf`` without the dot. The
    safe constructor reads them with ``float()``.
    """


_Loader.add_implicit_resolver(
    'tag:yaml.org,2002:float',
    re.compile(r'^[-+]?(?:\.[0-9]+|[0-9]+\.[0-9]*|[0-9]+)[eE][-+]?[0-9]+$'),
    list('-+.0123456789'))
_Loader.add_implicit_resolver('tag:yaml.org,2002:float',
                              re.compile(r'^[-+]?(?:nan|NaN|NAN|inf|Inf|INF)$'), list('-+nNiI'))


class ParamsFileError(ParameterError):
    """A parameters file that cannot be used, said in one line (``--params-file <path> ...``)."""

    def __init__(self, line: str) -> None:
        ValueError.__init__(self, line)
        self.name = '--params-file'
        self.reason = line


def _short(text: str, limit: int = 60) -> str:
    """Return ``text`` on one line, cut to ``limit`` characters."""
    line = ' '.join(text.split())
    return line if len(line) <= limit else line[:limit - 3] + '...'


def _check_events(text: str, refuse: Callable[[str], ParameterError]) -> None:
    """Refuse YAML beyond the limits, scanning the parser's events (nothing composed)."""
    depth = keys = nodes = 0
    items: list[int] = []          # per open collection: its count (-1 for a mapping)
    try:
        for event in yaml.parse(text, Loader=_Loader):
            if isinstance(event, (yaml.ScalarEvent, yaml.CollectionStartEvent)):
                nodes += 1
                if nodes > MAX_NODES:
                    raise refuse(f'more than {MAX_NODES} YAML values '
                                 f'(line {event.start_mark.line + 1})')
            if isinstance(event, yaml.AliasEvent) or getattr(event, 'anchor', None):
                raise refuse('YAML anchors and aliases are not accepted '
                             f'(line {event.start_mark.line + 1})')
            if isinstance(event, (yaml.ScalarEvent, yaml.CollectionStartEvent)) and items:
                if items[-1] >= 0:
                    items[-1] += 1
                    if items[-1] > MAX_ITEMS:
                        raise refuse(f'a list longer than {MAX_ITEMS} items '
                                     f'(line {event.start_mark.line + 1})')
                else:
                    keys += 1       # keys and values alternate: half are keys
                    if keys > 2 * MAX_KEYS:
                        raise refuse(f'more than {MAX_KEYS} keys')
            if isinstance(event, yaml.CollectionStartEvent):
                depth += 1
                if depth > MAX_DEPTH:
                    raise refuse(f'nested deeper than {MAX_DEPTH} '
                                 f'(line {event.start_mark.line + 1})')
                items.append(0 if isinstance(event, yaml.SequenceStartEvent) else -1)
            elif isinstance(event, yaml.CollectionEndEvent):
                depth -= 1
                items.pop()
    except yaml.YAMLError as error:
        mark = getattr(error, 'problem_mark', None)
        line = f' (line {mark.line + 1})' if mark is not None else ''
        problem = getattr(error, 'problem', None) or str(error)
        raise refuse(f'not valid YAML{line}: {_short(str(problem))}') from None


def parse_value(text: str, name: str) -> Any:
    """Return the value of ``-p NAME:=VALUE`` as rcl reads it (YAML 1.2 numbers)."""
    _check_events(text, lambda reason: ParameterError(name, reason))
    value = yaml.load(text, Loader=_Loader)  # noqa: S506 - a SafeLoader, checked above
    return value


def node_pattern_matches(pattern: str, node_fqn: str) -> bool:
    """
    Return whether a params-file key names the node ``node_fqn``, as rcl matches them.

    Keys are ``/**``, ``/**/navigator``, ``ns/navigator``...; ``node_fqn`` is ``/ns/navigator``.
    A key without a leading slash is absolute (rcl prepends one); ``/**`` stands for any
    number of namespace tokens, ``/*`` for exactly one.
    """
    key = pattern if pattern.startswith('/') else '/' + pattern
    regex = ''
    i = 0
    while i < len(key):
        if key.startswith('/**', i):
            regex += '(/[^/]+)*'
            i += 3
        elif key.startswith('/*', i):
            regex += '/[^/]+'
            i += 2
        else:
            regex += re.escape(key[i])
            i += 1
    return re.fullmatch(regex, node_fqn) is not None


def flatten(tree: Mapping[str, Any], prefix: str = '') -> dict[str, Any]:
    """Flatten nested YAML mappings into ROS dotted names: ``{'gnss': {'enabled': x}}``."""
    flat: dict[str, Any] = {}
    for key, value in tree.items():
        name = f'{prefix}{key}'
        if isinstance(value, Mapping):
            flat.update(flatten(value, name + '.'))
        else:
            flat[name] = value
    return flat


@dataclass
class ParamsFile:
    """
    What a parameters file sets for the navigator.

    ``values``: the navigator's parameters (ROS names, YAML types: ``max_gap: 2`` stays an
    integer, which :meth:`~.params.NavigatorParams.from_flat` takes as a double, as the node
    does); ``unknown``: other names in the node's sections (a typo?), ignored; ``ignored``: a
    line per removed name left at its neutral value; ``sections``: the keys that matched.
    """

    path: Path
    values: dict[str, Any] = field(default_factory=dict)
    unknown: list[str] = field(default_factory=list)
    ignored: list[str] = field(default_factory=list)
    sections: list[str] = field(default_factory=list)


def _sections(document: Mapping[Any, Any], node_fqn: str) -> Iterator[tuple[str, Any]]:
    for key, section in document.items():
        if isinstance(key, str) and node_pattern_matches(key, node_fqn):
            yield key, section


def read_params_file(path: str | Path, node_fqn: str = '/navigator') -> ParamsFile:
    """
    Read a ROS 2 parameters file; return what it sets for the node ``node_fqn``.

    Removed names are handled by :func:`without_removed`; names of :data:`FOREIGN_PREFIXES`
    are dropped; other unknown names are listed in ``unknown``.
    Raises :class:`ParamsFileError` (a :class:`~.params.ParameterError`) with one line when the
    file cannot be read, is beyond a limit, or is not a parameters file.
    """
    path = Path(path)
    if not node_fqn.startswith('/'):
        node_fqn = '/' + node_fqn

    def refuse(reason: str) -> ParamsFileError:
        return ParamsFileError(f'--params-file {path}: {reason}')
    try:
        with path.open('rb') as stream:
            data = stream.read(MAX_BYTES + 1)
    except OSError as error:
        raise ParamsFileError(f'cannot read --params-file {path}: {error.strerror}') from None
    if len(data) > MAX_BYTES:
        raise refuse(f'larger than {MAX_BYTES} bytes')
    try:
        text = data.decode('utf-8')
    except UnicodeDecodeError as error:
        raise refuse(f'not UTF-8 text (byte {error.start})') from None
    _check_events(text, refuse)
    document = yaml.load(text, Loader=_Loader)  # noqa: S506 - a SafeLoader, checked above
    if document is None:
        document = {}
    if not isinstance(document, Mapping):
        raise refuse('holds no mapping of node names')
    out = ParamsFile(path)
    values: dict[str, Any] = {}
    unknown: dict[str, None] = {}          # ordered, and a set
    for key, section in _sections(document, node_fqn):
        parameters = section.get('ros__parameters') if isinstance(section, Mapping) else None
        if not isinstance(parameters, Mapping):
            raise refuse(f'has no ros__parameters mapping in section {_short(key)!r}')
        out.sections.append(key)
        for name, value in flatten(parameters).items():
            name = str(name)
            if name.startswith(FOREIGN_PREFIXES):
                continue
            if name in _KNOWN or name in REMOVED:
                values[name] = value
            else:
                unknown[name] = None
    out.unknown = list(unknown)
    out.values, out.ignored = without_removed(values, str(path))
    return out


def without_removed(values: Mapping[str, Any], where: str) -> tuple[dict[str, Any], list[str]]:
    """
    Return ``values`` without the removed names (:data:`~.params.REMOVED`), and a line each.

    The line says what replaces the name, and, when its value meant something (``two_d:
    true``), that this meaning is not applied: set the replacement.
    """
    kept, lines = {}, []
    for name, value in values.items():
        if name not in REMOVED:
            kept[name] = value
            continue
        neutral, hint = REMOVED[name]
        lost = '' if type(value) is type(neutral) and value == neutral else (
            f'; {name}: {excerpt(value)} is NOT applied')
        lines.append(f'{where}: parameter {name!r} was removed and is ignored ({hint}{lost})')
    return kept, lines


def unknown_names_line(names: Sequence[str], where: str) -> str:
    """Return the one warning for names that are not the navigator's (the first few named)."""
    shown = ', '.join(repr(_short(n, 40)) for n in names[:5])
    more = f' and {len(names) - 5} more' if len(names) > 5 else ''
    return (f'{where}: {len(names)} name(s) are not navigator parameters, ignored (a typo?): '
            f'{shown}{more}')
