"""How every env constructor reaches the servers, written once: the connection keywords
(their names, defaults and meanings), the env options the server applies (read from the
protocol's table), the advice a user gets when no server answers, and the ``Connection``
they configure. A new connection keyword is added to ``_KEYWORDS`` (and used in
``Connection``) and nowhere else; a new env option is added to the protocol's table
(protocol/src/options.rs) and nowhere in Python: every constructor takes, documents,
lists and passes on the keywords of both tables."""

from __future__ import annotations

import inspect
import os
import re
import textwrap
import types
from typing import NamedTuple

from . import _core, _fork
from ._errors import InvalidEndpointError, ServerNotFoundError, clean, translate, translated

# Connection defaults are defined once, in the Rust protocol crate.
DEFAULT_CONNECT = _core.DEFAULT_CONNECT
DEFAULT_PREFIX = _core.DEFAULT_PREFIX
DEFAULT_TIMEOUT = _core.DEFAULT_TIMEOUT
DEFAULT_CONNECT_TIMEOUT = _core.DEFAULT_CONNECT_TIMEOUT
# Resends of a request that got no reply, by default (a step keeps its sequence number, so
# the server never steps twice): the Rust client's and the CLI's default too.
DEFAULT_RETRIES = 2
# The environment variable naming the endpoint when ``connect`` is not given.
CONNECT_VARIABLE = "HIGHWAY_ARENA_CONNECT"


class _Keyword(NamedTuple):
    default: object
    meaning: str


_KEYWORDS = {
    "connect": _Keyword(
        None,
        f"the server's Zenoh endpoint, PROTOCOL/HOST:PORT, or a list of them; default "
        f"${CONNECT_VARIABLE}, else {DEFAULT_CONNECT} (where arena-server listens by default)",
    ),
    "prefix": _Keyword(DEFAULT_PREFIX, f"the key prefix the servers answer under; default {DEFAULT_PREFIX!r}"),
    "timeout": _Keyword(
        DEFAULT_TIMEOUT, f"the seconds each attempt of a call waits for its reply; default {DEFAULT_TIMEOUT:g}"
    ),
    "retries": _Keyword(
        DEFAULT_RETRIES,
        f"resends of a call that got no reply (a step keeps its sequence number, so none runs "
        f"twice); default {DEFAULT_RETRIES}, as in the Rust client and the CLI",
    ),
    "connect_timeout": _Keyword(
        DEFAULT_CONNECT_TIMEOUT,
        f"the seconds to wait for a server to appear; default {DEFAULT_CONNECT_TIMEOUT:g}",
    ),
    "zenoh_config": _Keyword(
        None,
        "a Zenoh JSON5 file: the user and password, and TLS, of a deployment with access "
        "control (e.g. deploy/auth/client.json5, see docs/deployment.md)",
    ),
    "mode": _Keyword(None, "the Zenoh session mode: 'client' through a router; default 'peer', or the config file's"),
}

# The connection keywords and their defaults, in the order constructors list them.
CONNECTION_KEYWORDS = types.MappingProxyType({name: keyword.default for name, keyword in _KEYWORDS.items()})

# What each connection keyword means, as the docstrings of the constructors end.
CONNECTION_HELP = "Connection keywords (``highway_arena.CONNECTION_KEYWORDS``):\n\n" + "\n".join(
    textwrap.fill(f"- ``{name}``: {keyword.meaning}.", width=88, subsequent_indent="  ")
    for name, keyword in _KEYWORDS.items()
)


def default_connect() -> str:
    """$HIGHWAY_ARENA_CONNECT, else tcp/127.0.0.1:7447 (arena-server's default)."""
    return os.environ.get(CONNECT_VARIABLE, DEFAULT_CONNECT)


def split(kwargs: dict, **named) -> tuple[dict, dict]:
    """The connection keywords given among ``kwargs`` and ``named`` (those a constructor
    names in its own signature, such as ``connect``), and the other keywords. Keywords
    left out are left out (``Connection`` fills in the defaults)."""
    given = {**kwargs, **named}
    connection = {name: given[name] for name in CONNECTION_KEYWORDS if name in given}
    rest = {name: value for name, value in kwargs.items() if name not in CONNECTION_KEYWORDS}
    return connection, rest


def keywords(function) -> list[str]:
    """The keyword names ``function`` takes by name, connection keywords included (once
    ``takes_connection_keywords`` has shown them in its signature)."""
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    names = [p.name for p in inspect.signature(function).parameters.values() if p.kind in kinds and p.name != "self"]
    return names + [name for name in CONNECTION_KEYWORDS if name not in names]


# The env options a server applies at creation, declared once in arena-protocol
# (protocol/src/options.rs) and read from the extension as (name, default, what it
# takes, what it does). Two of the protocol's options are taken their own way, not as
# keywords of these names and values: ``overrides`` (a dict, or ``a__b`` keywords) and
# ``record`` (where to record: a path or a folder).
_OWN_WAY = ("overrides", "record")
_ENV_OPTIONS = [option for option in _core.CREATE_OPTIONS if option[0] not in _OWN_WAY]

# The env options and their defaults (None: the scenario's, or the server's), in the
# protocol's order.
ENV_OPTIONS = types.MappingProxyType({name: default for name, default, _, _ in _ENV_OPTIONS})


def _rst(text: str) -> str:
    """The protocol's docs write code in single backticks; docstrings in double."""
    return re.sub(r"`([^`]+)`", r"``\1``", text)


# What each env option means, as the docstrings of the constructors that take them end.
ENV_OPTIONS_HELP = "Env options (``highway_arena.ENV_OPTIONS``, applied by the server):\n\n" + "\n".join(
    textwrap.fill(f"- ``{name}`` ({takes}): {_rst(doc)}", width=88, subsequent_indent="  ", break_on_hyphens=False)
    for name, _, takes, doc in _ENV_OPTIONS
)


def env_options(kwargs: dict) -> dict:
    """Takes the env options out of ``kwargs`` (a constructor's other keywords), as one
    dict for ``Connection.create``."""
    return {name: kwargs.pop(name) for name in ENV_OPTIONS if name in kwargs}


def _shows(constructor, what: str, defaults, help_text: str):
    """Shows ``defaults``' keywords in the signature of ``constructor`` (whose ``**kwargs``
    take them) as keyword-only parameters with their defaults, those it does not name
    itself, and ends its docstring with ``help_text``."""
    function = constructor.__init__ if isinstance(constructor, type) else constructor
    signature = inspect.signature(function)
    parameters = list(signature.parameters.values())
    if not parameters or parameters[-1].kind is not inspect.Parameter.VAR_KEYWORD:
        raise TypeError(f"{function.__qualname__} needs **kwargs to take the {what}")
    named = {p.name for p in parameters}
    shown = [
        inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=default)
        for name, default in defaults.items()
        if name not in named
    ]
    function.__signature__ = signature.replace(parameters=[*parameters[:-1], *shown, parameters[-1]])
    constructor.__doc__ = f"{inspect.cleandoc(constructor.__doc__ or '')}\n\n{help_text}"
    return constructor


def takes_connection_keywords(constructor):
    """Marks a class or function whose ``**kwargs`` take the connection keywords: its
    signature (``help()``, IDEs, ``keywords()``) shows them as keyword-only parameters with
    their defaults, and its docstring ends with what each means."""
    return _shows(constructor, "connection keywords", CONNECTION_KEYWORDS, CONNECTION_HELP)


def takes_env_options(constructor):
    """Marks a class or function whose ``**kwargs`` take the env options, as
    ``takes_connection_keywords`` does the connection keywords (apply it first: the env
    options come before the connection keywords)."""
    return _shows(constructor, "env options", ENV_OPTIONS, ENV_OPTIONS_HELP)


# A Zenoh endpoint: <protocol>/<address>[?<metadata>][#<config>].
_ENDPOINT = re.compile(r"^[A-Za-z][A-Za-z0-9_+-]*/\S+$")

# The advice a user gets when the endpoint is unusable or nobody answers there.
ENDPOINT_FORM = f"write PROTOCOL/HOST:PORT, e.g. {DEFAULT_CONNECT} (where arena-server listens by default)"


def no_session_advice(where: str) -> str:
    """A Zenoh client session needs its router at once; a peer does not."""
    return (
        f"nothing at {where} accepted a Zenoh session: is the router running and listening there, and "
        "does it ask for credentials (pass zenoh_config= a file with your user and password, see "
        "docs/deployment.md)?"
    )


def no_server_advice(where: str, prefix: str, endpoint: str) -> str:
    """No arena-server answered on a session that opened."""
    return (
        f"no arena-server answered at {where} (prefix {prefix!r}): is one running and listening there? "
        f"Start one with `arena-server --listen {endpoint}` on that machine, pass connect= the "
        "endpoint yours listens on, or use highway_arena.launch_server() to start a local one"
    )


def _endpoints(connect) -> list[str]:
    if connect is None:
        connect = default_connect()
    endpoints = [connect] if isinstance(connect, str) else list(connect)
    if not endpoints:
        raise InvalidEndpointError("InvalidEndpoint", f"connect= names no endpoint; {ENDPOINT_FORM}")
    for endpoint in endpoints:
        if not isinstance(endpoint, str) or not _ENDPOINT.match(endpoint):
            raise InvalidEndpointError(
                "InvalidEndpoint", f"connect={endpoint!r} is not a Zenoh endpoint; {ENDPOINT_FORM}"
            )
    return endpoints


def _seconds(name: str, value) -> float:
    seconds = float(value)
    if not seconds > 0 or seconds == float("inf"):
        raise ValueError(f"{name} must be a positive number of seconds, not {seconds}")
    return seconds


class Connection:
    """One Zenoh session and the server picked on it, configured by the connection
    keywords (``CONNECTION_KEYWORDS``; any other is refused)."""

    def __init__(self, **keywords):
        unknown = sorted(set(keywords) - set(CONNECTION_KEYWORDS))
        if unknown:
            raise TypeError(f"unknown connection keyword(s) {unknown}; they are {', '.join(CONNECTION_KEYWORDS)}")
        settings = {**CONNECTION_KEYWORDS, **keywords}
        endpoints = _endpoints(settings["connect"])
        prefix = settings["prefix"]
        timeout = _seconds("timeout", settings["timeout"])
        connect_timeout = _seconds("connect_timeout", settings["connect_timeout"])
        retries = settings["retries"]
        if isinstance(retries, bool) or not isinstance(retries, int) or not 0 <= retries <= 100:
            raise ValueError(f"retries must be a whole number of resends from 0 to 100, not {retries!r}")
        zenoh_config = settings["zenoh_config"]
        where = ", ".join(endpoints)
        try:
            self.client = _fork.extension().Client(
                endpoints,
                prefix=prefix,
                timeout=timeout,
                retries=retries,
                zenoh_config=None if zenoh_config is None else str(zenoh_config),
                mode=settings["mode"],
            )
        except _fork.errors as error:
            code, message = error.args
            if code == "Forked":
                raise translate(error) from None
            if "Unable to connect" in message:
                raise ServerNotFoundError("NoServer", no_session_advice(where)) from None
            raise InvalidEndpointError(
                "InvalidEndpoint", f"cannot open a Zenoh session to {where}: {clean(message)}; {ENDPOINT_FORM}"
            ) from None
        try:
            self.client.pick_server(wait=min(connect_timeout, timeout))
            # Of every server found, the least loaded (see ``place``).
            self.server = self.client.place(1)[0]
        except _fork.errors as error:
            self.client.close()
            code, _ = error.args
            if code != "NoServer":
                raise translate(error) from None
            raise ServerNotFoundError(code, no_server_advice(where, prefix, endpoints[0])) from None

    @translated
    def place(self, count):
        """Servers for ``count`` new envs, spread over every server found by load (fewest
        envs per core first): a vector env's envs land on all the servers of a site."""
        return self.client.place(count)

    @translated
    def create(self, scenario, scenario_text=None, overrides=None, server=None, record=False, **options):
        """An env on ``server`` (default: the one picked at connection). ``options`` are
        the env's options on the server (``ENV_OPTIONS``); ``record`` (taken its own way by
        the constructors: envs made of several do not record) has replies carry the world."""
        return self.client.create_env(
            server or self.server,
            scenario,
            scenario_text,
            overrides=dict(overrides or {}),
            record=bool(record),
            **options,
        )

    @translated
    def close(self):
        self.client.close()
