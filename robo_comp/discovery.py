"""Finding the core on the LAN by name: mDNS / DNS-SD with ``zeroconf`` (the thesis's "is anyone
out there?").

The core advertises itself only when the organiser asks (``robo-comp core --advertise NAME``):
a DNS-SD service ``NAME._robocomp._tcp.local.`` with the ROUTER's address and port, and in its
TXT record the PUB port, whether CurveZMQ is on and the protocol version. Clients give
``--core mdns:NAME`` wherever they take a core (``robots``, ``team``, ``referee``, ``wall``,
``web``, ``ctl``): :func:`robo_comp.client.resolve_core` asks here for the URL.

Interfaces. A core bound to one address (``--host 10.0.0.5``, or the default 127.0.0.1)
advertises on that address's interface only; a core bound to ``0.0.0.0`` on every interface.
``$ROBO_COMP_MDNS_INTERFACES`` (comma-separated IPv4 addresses) pins both sides to those
interfaces: tests and benches set it to ``127.0.0.1`` so no multicast leaves the machine.

Trust. mDNS answers are not authenticated: anyone on the LAN can answer for a name. A client
sends its token in its first message, so on a LAN the organiser does not trust, use CurveZMQ
(``core --curve``; clients ``--core-key``): a core that is not the organiser's cannot complete the
handshake, and no token leaves in the clear ([security.md](../docs/security.md)).
"""
from __future__ import annotations

import os
import re
import socket
import threading
import time
from dataclasses import dataclass
from typing import Any

from robo_comp.errors import FieldError, UnavailableError

SERVICE = "_robocomp._tcp.local."
ENV_INTERFACES = "ROBO_COMP_MDNS_INTERFACES"
#: How long a client waits for the core's answer (seconds).
TIMEOUT = 3.0
#: How long the core waits for another core answering to its name before it takes the name.
CLASH_SECONDS = 2.0
#: How long a found address is reused without asking again (seconds).
CACHE_SECONDS = 10.0
_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9-]{0,62}")

_cache: dict[str, tuple[float, str]] = {}
_cache_lock = threading.Lock()


def check_name(name: str) -> str:
    """``name`` if it can name a core on the LAN (letters, digits and ``-``; 1–63 characters)."""
    if not _NAME.fullmatch(name or ""):
        raise FieldError(f"{name!r} cannot name a core on the LAN: use 1-63 letters, digits and '-' "
                         "(starting with a letter or digit)")
    return name


def _interfaces(bound_host: str | None = None) -> Any:
    """Zeroconf's ``interfaces``: $ROBO_COMP_MDNS_INTERFACES, else the core's own address, else all."""
    from zeroconf import InterfaceChoice

    env = os.environ.get(ENV_INTERFACES, "").strip()
    if env:
        return [a.strip() for a in env.split(",") if a.strip()]
    if bound_host and bound_host not in ("0.0.0.0", "*", ""):
        return [bound_host]
    return InterfaceChoice.All


def _zeroconf(interfaces: Any) -> Any:
    try:
        from zeroconf import IPVersion, Zeroconf
    except ImportError:
        raise UnavailableError("finding the core by name needs zeroconf: pip install 'robo_comp[mdns]'") from None
    try:
        return Zeroconf(interfaces=interfaces, ip_version=IPVersion.V4Only)
    except OSError as e:
        raise UnavailableError(f"cannot use mDNS on {interfaces}: {e.strerror or e}") from None


def _addresses(host: str, interfaces: Any) -> list[str]:
    """The IPv4 addresses to advertise for a core bound to ``host``."""
    if host not in ("0.0.0.0", "*", ""):
        return [socket.gethostbyname(host)]
    if isinstance(interfaces, list):
        return interfaces
    import ifaddr  # zeroconf's own dependency

    return [ip.ip for a in ifaddr.get_adapters() for ip in a.ips
            if isinstance(ip.ip, str) and not ip.ip.startswith("127.")] or ["127.0.0.1"]


@dataclass
class Advertisement:
    """A core's DNS-SD service while it is registered; :meth:`close` withdraws it."""

    name: str
    zc: Any
    info: Any

    def close(self) -> None:
        """Withdraw the service (a goodbye packet) and stop answering."""
        try:
            self.zc.unregister_service(self.info)
        finally:
            self.zc.close()


def advertise(name: str, host: str, port: int, pub_port: int, *, curve: bool = False,
              protocol: int | None = None) -> Advertisement:
    """Advertise the core ``name`` (ROUTER on ``host:port``) on the LAN until closed. A name another
    core already answers for is refused."""
    from zeroconf import NonUniqueNameException, ServiceInfo

    check_name(name)
    interfaces = _interfaces(host)
    addrs = _addresses(host, interfaces)
    props = {"pub": str(pub_port), "curve": "1" if curve else "0"}
    if protocol is not None:
        props["protocol"] = str(protocol)
    info = ServiceInfo(SERVICE, f"{name}.{SERVICE}", port=int(port), properties=props,
                       addresses=[socket.inet_aton(a) for a in addrs], server=f"{name}-robocomp.local.")
    zc = _zeroconf(interfaces)
    try:
        # zeroconf's own probe finds a clash only when it has the other's PTR record cached: ask
        # for the name first (two seconds of waiting when nobody answers, once at the core's start;
        # a responder answers the same record at most once a second, so one second is too short)
        other = zc.get_service_info(SERVICE, info.name, timeout=int(CLASH_SECONDS * 1000))
        if other is not None:
            raise NonUniqueNameException(info.name)
        zc.register_service(info)
    except NonUniqueNameException:
        zc.close()
        raise FieldError(f"another core already answers to the name {name!r} on this network: "
                         "choose another --advertise NAME") from None
    except BaseException:
        zc.close()
        raise
    return Advertisement(name, zc, info)


@dataclass(frozen=True, slots=True)
class FoundCore:
    """A core found by name: its ROUTER URL and what its TXT record says."""

    url: str
    pub_port: int | None
    curve: bool


def find(name: str, timeout: float = TIMEOUT) -> FoundCore:
    """Ask the LAN for the core ``name``; an error saying what to check when none answers."""
    check_name(name)
    zc = _zeroconf(_interfaces())
    try:
        info = zc.get_service_info(SERVICE, f"{name}.{SERVICE}", timeout=int(timeout * 1000))
    finally:
        zc.close()
    if info is None or not info.parsed_addresses():
        raise UnavailableError(f"no core named {name!r} answered on the LAN within {timeout:g} s: is it running "
                               f"with --advertise {name}, on this network (mDNS needs multicast)? "
                               "Else give --core tcp://HOST:PORT")
    props = {k.decode(errors="replace"): (v or b"").decode(errors="replace") for k, v in info.properties.items()}
    pub = props.get("pub", "")
    return FoundCore(f"tcp://{info.parsed_addresses()[0]}:{info.port}", int(pub) if pub.isdigit() else None,
                     props.get("curve") == "1")


def resolve(name: str, timeout: float = TIMEOUT) -> str:
    """The ROUTER URL of the core ``name`` (asked again after :data:`CACHE_SECONDS`)."""
    now = time.monotonic()
    with _cache_lock:
        hit = _cache.get(name)
        if hit is not None and now - hit[0] < CACHE_SECONDS:
            return hit[1]
    url = find(name, timeout).url
    with _cache_lock:
        _cache[name] = (time.monotonic(), url)
    return url
