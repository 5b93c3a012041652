"""DDS on one domain and one network interface, with raw-bytes writers and readers for the hot path.

Both plants use it: the hardware interface (client: publishes ``rt/lowcmd``, reads ``rt/lowstate``)
and the MuJoCo bridge (the reverse). Topics are registered with Unitree's IDL types (from the
``unitree-sdk2py-dimos`` package) so the type names and type information match the robot's, but
messages are written and taken as serialized bytes: cyclonedds' ``DataWriter.write`` serializes
an ``IdlStruct`` field by field in Python (~180 us per LowCmd_ measured here, bench/bench_dds.py)
while the numpy codec (:mod:`mbctl.unitree.wire`) makes the same bytes in a few us. The
raw calls are the ones cyclonedds' own ``write`` and ``take`` make after (de)serializing
(``ddspy_write``, ``ddspy_take``); tests check they round-trip with the public API.

Network safety: the participant is configured for exactly one interface. ``lo`` (the default
everywhere in mbctl) gets multicast discovery on ``lo`` (multicast sent on the loopback interface
stays on the machine) plus unicast to 127.0.0.1, so no packet leaves the machine; it is what Unitree's
SDK configures on ``lo`` (``ChannelFactoryInitialize(domain, "lo")``: Cyclone's defaults on that
interface, multicast included), so mbctl and Unitree's simulator or SDK programs discover each
other there. Any other interface must be named by the user (a real robot's, e.g. ``enp3s0``) and
gets Cyclone's defaults on that interface only. Cyclone binds its receive sockets to 0.0.0.0
whatever the configuration says (:mod:`mbctl.unitree.sockets`): on Linux each is pinned to the
configured interface once the domain is made (``SO_BINDTODEVICE``), so the kernel delivers to it
only packets that arrived there; for anything else (several interfaces, a discovery
server, peers) the user gives a Cyclone configuration file of their own (``config``), used as
written. Waiting (``RawReader.wait``) blocks in C through ctypes, which releases the GIL.

One writer per topic: a second bridge or a second client on the domain would mix two plants'
states or two controllers' commands. :meth:`Channel.writers` counts the writers of a topic that
discovery has matched (the process's own included), so the bridge and the client refuse to start
beside another writer of the topic they write (:class:`AnotherWriterError`). Discovery is not
instantaneous: :data:`DISCOVERY_S` is how long a start waits for one to show (a reader matched an
existing writer of another process on ``lo`` after 33-34 ms on an idle machine, 42-236 ms at load
average 6.6); a writer discovery finds later is not seen by that check.
"""

from __future__ import annotations

import socket
import threading
import time
from typing import Any

from mbctl.unitree import sockets
from mbctl.unitree.exceptions import AnotherWriterError, ChannelError

TOPIC_LOWCMD = "rt/lowcmd"
TOPIC_LOWSTATE = "rt/lowstate"
LOOPBACK = "lo"
#: How long [s] a start waits for discovery to show another writer of its topic.
DISCOVERY_S = 0.5
#: DDS domain ids Cyclone accepts (the port of domain d is 7400 + 250 d, below 65536).
MAX_DOMAIN = 232

_LOOPBACK_CONFIG = """<CycloneDDS><Domain Id="any">
<General><Interfaces><NetworkInterface name="lo" multicast="true"/></Interfaces>
<AllowMulticast>true</AllowMulticast></General>
<Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>30</MaxAutoParticipantIndex>
<Peers><Peer address="127.0.0.1"/></Peers></Discovery>
<Tracing><Verbosity>none</Verbosity></Tracing>
</Domain></CycloneDDS>"""

_INTERFACE_CONFIG = """<CycloneDDS><Domain Id="any">
<General><Interfaces><NetworkInterface name="{name}" priority="default" multicast="default"/></Interfaces>
</General><Tracing><Verbosity>none</Verbosity></Tracing>
</Domain></CycloneDDS>"""


def _dds() -> dict[str, Any]:
    """The cyclonedds names used here, or ChannelError saying how to install them."""
    try:
        import cyclonedds._clayer as clayer
        from cyclonedds import core, domain, pub, qos, sub, topic
    except ImportError as exc:
        raise ChannelError(f"DDS needs the hardware extra: pip install 'mbctl[hardware]' ({exc})") from None
    return {"clayer": clayer, "Domain": domain.Domain, "DomainParticipant": domain.DomainParticipant,
            "Topic": topic.Topic, "DataWriter": pub.DataWriter, "DataReader": sub.DataReader,
            "Qos": qos.Qos, "Policy": qos.Policy, "WaitSet": core.WaitSet,
            "ReadCondition": core.ReadCondition, "SampleState": core.SampleState,
            "ViewState": core.ViewState, "InstanceState": core.InstanceState}


def message_types() -> tuple[type, type]:
    """Unitree's ``unitree_hg`` (LowCmd_, LowState_) IDL types.

    Raises:
        ChannelError: The hardware extra is not installed.
    """
    try:
        from unitree_sdk2py.idl.unitree_hg.msg.dds_ import LowCmd_, LowState_
    except ImportError as exc:
        raise ChannelError(f"DDS needs the hardware extra: pip install 'mbctl[hardware]' ({exc})") from None
    return LowCmd_, LowState_


def check_domain(domain: int) -> int:
    """``domain`` as an int in 0..232; ChannelError otherwise."""
    if isinstance(domain, bool) or not isinstance(domain, int) or not 0 <= domain <= MAX_DOMAIN:
        raise ChannelError(f"DDS domain must be an integer in 0..{MAX_DOMAIN}; got {domain!r}")
    return domain


def check_network_interface(name: str) -> str:
    """``name`` if this machine has that network interface; ChannelError listing the ones it has."""
    known = [n for _, n in socket.if_nameindex()]
    if name not in known:
        raise ChannelError(f"no network interface {name!r} on this machine; it has: {', '.join(known)} "
                           f"(the default is {LOOPBACK!r}; name the interface wired to the robot)")
    return name


def domain_config(network_interface: str, config_file: str | None = None) -> str:
    """The Cyclone DDS configuration (XML) for one network interface, or the user's file as written.

    Args:
        network_interface: ``lo`` or the interface wired to the robot (see the module docstring).
        config_file: A Cyclone DDS configuration file of the user's (None: the one made here).

    Raises:
        ChannelError: ``config_file`` cannot be read.
    """
    if config_file is not None:
        try:
            with open(config_file, encoding="utf-8") as f:
                return f.read()
        except OSError as exc:
            raise ChannelError(f"cannot read the Cyclone DDS configuration {config_file!r}: {exc}; give a "
                               "readable XML file (or none: mbctl configures the named interface)") from None
    if network_interface == LOOPBACK:
        return _LOOPBACK_CONFIG
    return _INTERFACE_CONFIG.format(name=network_interface)


# Cyclone allows one configuration per domain id per process: domains are shared and counted.
_domains: dict[int, tuple[Any, str, int]] = {}
_domains_lock = threading.Lock()


def _acquire_domain(domain: int, network_interface: str, config_file: str | None = None) -> None:
    where = network_interface if config_file is None else f"{network_interface} ({config_file})"
    with _domains_lock:
        held = _domains.get(domain)
        if held is not None:
            if held[1] != where:
                raise ChannelError(f"DDS domain {domain} is already open on {held[1]!r} in this process; "
                                   f"cannot also open it on {where!r}")
            _domains[domain] = (held[0], held[1], held[2] + 1)
            return
        dds = _dds()
        config = domain_config(network_interface, config_file)
        before = sockets.inodes()
        try:
            handle = dds["Domain"](domain, config)
        except Exception as exc:  # cyclonedds.core.DDSException: e.g. no such interface
            raise ChannelError(f"cannot create DDS domain {domain} on network interface "
                               f"{network_interface!r}: {exc}") from exc
        if config_file is None:  # the user's configuration is used as written
            try:
                sockets.pin_new_sockets(before, network_interface)
            except ChannelError:
                del handle  # deletes the domain and its sockets
                raise
        _domains[domain] = (handle, where, 1)


def _release_domain(domain: int) -> None:
    with _domains_lock:
        held = _domains.get(domain)
        if held is None:
            return
        if held[2] > 1:
            _domains[domain] = (held[0], held[1], held[2] - 1)
        else:
            del _domains[domain]


class RawWriter:
    """Publishes already serialized messages on one topic."""

    def __init__(self, writer: Any, write: Any):
        self._writer = writer
        self._ref = writer._ref
        self._write = write

    def write(self, payload: bytes) -> None:
        """Publish ``payload`` (encapsulation header + serialized message, a multiple of 4 bytes).

        Raises:
            ChannelError: DDS refused the sample.
        """
        ret = self._write(self._ref, payload)
        if ret < 0:
            raise ChannelError(f"DDS write failed with return code {ret}")

    def matched(self) -> int:
        """How many readers of this topic discovery has matched with this writer.

        A sample written before the robot's reader matched is lost.
        """
        return int(self._writer.get_publication_matched_status().current_count)


class RawReader:
    """Takes serialized messages of one topic; waits for them with the GIL released."""

    def __init__(self, dds: dict[str, Any], reader: Any):
        self._reader = reader
        self._ref = reader._ref
        self._take = dds["clayer"].ddspy_take
        self._mask = dds["SampleState"].Any | dds["ViewState"].Any | dds["InstanceState"].Any
        self._waitset = dds["WaitSet"](reader.participant)
        self._condition = dds["ReadCondition"](reader, self._mask)
        self._waitset.attach(self._condition)

    def take(self, max_samples: int = 16) -> list[bytes]:
        """Every sample waiting (up to ``max_samples``), oldest first, as wire bytes."""
        samples = self._take(self._ref, self._mask, max_samples)
        if isinstance(samples, int):
            raise ChannelError(f"DDS take failed with return code {samples}")
        return [data for data, info in samples if info.valid_data]

    def wait(self, timeout_s: float) -> bool:
        """Block (GIL released) until a sample is waiting or ``timeout_s`` passed; whether one is."""
        return self._waitset.wait(max(0, int(timeout_s * 1e9))) > 0

    def matched(self) -> int:
        """How many writers of this topic discovery has matched with this reader."""
        return int(self._reader.get_subscription_matched_status().current_count)


class WriterCount:
    """The writers of one topic that discovery has matched on the domain (this participant's included).

    A reader of the topic held only to count them (it keeps one sample; nothing reads it).
    """

    def __init__(self, reader: Any, topic: str):
        self._reader = reader
        self.topic = topic

    def count(self) -> int:
        """How many writers of the topic are matched now."""
        return int(self._reader.get_subscription_matched_status().current_count)

    def others(self, own: int, until: float) -> int:
        """Writers beyond ``own`` (this process's), waiting until ``until`` [s, perf_counter] for one."""
        while True:
            extra = self.count() - own
            if extra > 0 or time.perf_counter() >= until:
                return max(extra, 0)
            time.sleep(0.005)

    def refuse_others(self, own: int, until: float, what: str, domain: int, network_interface: str) -> None:
        """Raise :class:`AnotherWriterError` if a writer beyond ``own`` shows by ``until``.

        Args:
            own: This process's writers of the topic.
            until: When to stop waiting for discovery (``time.perf_counter``) [s].
            what: Who is starting and what the other writer may be, for the message.
            domain: The DDS domain (in the message).
            network_interface: The network interface (in the message).
        """
        extra = self.others(own, until)
        if extra:
            raise AnotherWriterError(
                f"{what}: {extra} other writer{'s' if extra > 1 else ''} of {self.topic} already on DDS "
                f"domain {domain} (network interface {network_interface!r}); refusing to start beside it. "
                "Stop it, or use another --domain.")

    def close(self) -> None:
        """Stop counting: delete the reader (idempotent; the channel's close deletes it too)."""
        self._reader.__del__()


class Channel:
    """A DDS participant on one domain and one network interface.

    Args:
        domain: DDS domain id (0..232); the robot uses 0, tests use a unique one each.
        network_interface: ``lo`` (default) or the interface wired to the robot.
        config_file: The user's own Cyclone DDS configuration file, used as written (None: the
            configuration of ``network_interface`` made here).

    Raises:
        ChannelError: The hardware extra is missing, a bad domain id, an unknown interface or an
            unreadable configuration file.
    """

    def __init__(self, domain: int = 0, network_interface: str = LOOPBACK, config_file: str | None = None):
        self.domain = check_domain(domain)
        self.network_interface = check_network_interface(network_interface)
        self._dds = _dds()
        _acquire_domain(self.domain, self.network_interface, config_file)
        try:
            self._participant = self._dds["DomainParticipant"](self.domain)
        except Exception as exc:
            _release_domain(self.domain)
            raise ChannelError(f"cannot join DDS domain {domain} on {network_interface!r}: {exc}") from exc
        self._topics: dict[str, Any] = {}
        self._entities: list[Any] = []
        self._closed = False

    def _topic(self, name: str, data_type: type) -> Any:
        if name not in self._topics:
            self._topics[name] = self._dds["Topic"](self._participant, name, data_type)
        return self._topics[name]

    def writer(self, topic: str, data_type: type) -> RawWriter:
        """A writer of ``topic`` (reliable, keep last 1: Cyclone's writer defaults, as Unitree's SDK)."""
        w = self._dds["DataWriter"](self._participant, self._topic(topic, data_type))
        self._entities.append(w)
        return RawWriter(w, self._dds["clayer"].ddspy_write)

    def reader(self, topic: str, data_type: type, depth: int = 16) -> RawReader:
        """A best-effort reader of ``topic`` keeping the last ``depth`` samples."""
        Policy, Qos = self._dds["Policy"], self._dds["Qos"]
        qos = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(depth))
        r = self._dds["DataReader"](self._participant, self._topic(topic, data_type), qos=qos)
        raw = RawReader(self._dds, r)
        self._entities += [r, raw._condition, raw._waitset]
        return raw

    def writers(self, topic: str, data_type: type) -> WriterCount:
        """Count the writers of ``topic`` on the domain from now on (discovery matches them over time)."""
        Policy, Qos = self._dds["Policy"], self._dds["Qos"]
        qos = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(1))
        r = self._dds["DataReader"](self._participant, self._topic(topic, data_type), qos=qos)
        self._entities.append(r)
        return WriterCount(r, topic)

    def close(self) -> None:
        """Delete the participant and everything it owns (idempotent)."""
        if self._closed:
            return
        self._closed = True
        participant, self._participant = self._participant, None
        self._entities.clear()
        self._topics.clear()
        # Deleting the participant in C deletes its readers, writers, topics and waitsets now,
        # whoever still holds their Python objects (cyclonedds deletes an entity in __del__ and
        # then forgets it, so the children's own __del__ later is a no-op error code).
        participant.__del__()
        _release_domain(self.domain)

    def __enter__(self) -> Channel:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
