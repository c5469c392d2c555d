"""The DDS side of the ROS 2 driver: participants, ROS 2 topic names and QoS, the loopback config.

ROS 2 maps a topic ``/ns/name`` to the DDS topic ``rt/ns/name`` (``rt`` for "ROS topic") and
every ROS 2 node of a domain id is one DDS domain. One :class:`Bus` per domain id is shared by
all robots of a host (one DDS participant, as one ROS 2 process has one).

QoS as ROS 2's defaults: commands are written *reliable*, volatile, keep last 10 (what
``ros2 topic pub /cmd_vel`` and Nav2 use, and matched by best-effort readers too); odometry
and scans are read *best effort* (a best-effort reader matches reliable and best-effort
writers: TurtleBot 4 publishes ``/scan`` with the sensor-data QoS, best effort).
"""
from __future__ import annotations

import os
import threading
from typing import Any

from robo_comp.errors import UnavailableError

#: The highest ROS 2 domain id (ROS_DOMAIN_ID: 0..232 on Linux; 101 and up collide with
#: ephemeral ports on some systems, see the ROS 2 docs on domain ids).
MAX_DOMAIN_ID = 232


def loopback_config(domain_id: int | None = None) -> str:
    """A Cyclone DDS configuration (XML text, as ``CYCLONEDDS_URI`` takes it) that keeps every
    discovery and data packet on the loopback interface: interface ``lo``, no multicast,
    127.0.0.1 as the only peer, participant indices assigned automatically (so several
    processes on one machine find each other by unicast). For tests and benches."""
    dom = "any" if domain_id is None else str(int(domain_id))
    return (f'<CycloneDDS><Domain Id="{dom}"><General><Interfaces><NetworkInterface name="lo"/></Interfaces>'
            "<AllowMulticast>false</AllowMulticast></General>"
            "<Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>30</MaxAutoParticipantIndex>"
            '<Peers><Peer Address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>')


def topic_name(namespace: str, name: str) -> str:
    """The DDS topic of the ROS 2 topic ``name`` in ``namespace``: ``rt/<ns>/<name>``
    (``rt/<name>`` without a namespace)."""
    ns = namespace.strip("/")
    return f"rt/{ns}/{name}" if ns else f"rt/{name}"


def check_domain(domain_id: int) -> int:
    """``domain_id`` if it is a ROS 2 domain id, else a clear error."""
    if not 0 <= int(domain_id) <= MAX_DOMAIN_ID:
        raise UnavailableError(f"ROS 2 domain id {domain_id} is out of range: give 0..{MAX_DOMAIN_ID} "
                               "(the robots' ROS_DOMAIN_ID)")
    return int(domain_id)


def _import_dds() -> Any:
    try:
        import cyclonedds.domain  # noqa: F401
    except ImportError:
        raise UnavailableError("the ROS 2 driver needs Cyclone DDS: pip install 'robo_comp[ros2]'") from None
    import cyclonedds

    return cyclonedds


class Bus:
    """One DDS participant on one ROS 2 domain id, with readers and writers made from it.

    The Cyclone DDS configuration is the environment's (``CYCLONEDDS_URI``), as for any ROS 2
    program using Cyclone DDS; tests set it to :func:`loopback_config`.
    """

    _shared: dict[int, Bus] = {}
    _lock = threading.Lock()

    def __init__(self, domain_id: int = 0) -> None:
        _import_dds()
        from cyclonedds.domain import DomainParticipant

        self.domain_id = check_domain(domain_id)
        try:
            self.participant = DomainParticipant(self.domain_id)
        except Exception as e:  # a bad CYCLONEDDS_URI, no such interface
            raise UnavailableError(f"cannot join ROS 2 domain {domain_id} over DDS: {e} "
                                   f"(CYCLONEDDS_URI={os.environ.get('CYCLONEDDS_URI', '')[:200]!r})") from None
        self._topics: dict[str, Any] = {}

    @classmethod
    def shared(cls, domain_id: int = 0) -> Bus:
        """The host-wide bus of ``domain_id`` (made on first use)."""
        with cls._lock:
            bus = cls._shared.get(domain_id)
            if bus is None:
                bus = cls._shared[domain_id] = cls(domain_id)
            return bus

    def topic(self, name: str, kind: type) -> Any:
        """The DDS topic ``name`` of type ``kind`` (one per name on this participant)."""
        from cyclonedds.topic import Topic

        t = self._topics.get(name)
        if t is None:
            t = self._topics[name] = Topic(self.participant, name, kind)
        return t

    def writer(self, name: str, kind: type, *, depth: int = 10) -> Any:
        """A reliable, volatile writer (ROS 2's default publisher QoS)."""
        from cyclonedds.core import Policy, Qos
        from cyclonedds.pub import DataWriter
        from cyclonedds.util import duration

        qos = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(depth),
                  Policy.Durability.Volatile)
        return DataWriter(self.participant, self.topic(name, kind), qos=qos)

    def reader(self, name: str, kind: type, *, depth: int = 10, reliable: bool = False) -> Any:
        """A reader, best effort unless ``reliable`` (best effort matches every ROS 2 publisher)."""
        from cyclonedds.core import Policy, Qos
        from cyclonedds.sub import DataReader
        from cyclonedds.util import duration

        rel = Policy.Reliability.Reliable(duration(milliseconds=100)) if reliable else Policy.Reliability.BestEffort
        qos = Qos(rel, Policy.History.KeepLast(depth), Policy.Durability.Volatile)
        return DataReader(self.participant, self.topic(name, kind), qos=qos)
