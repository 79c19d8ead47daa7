"""UDP endpoints ``udp://HOST:PORT``: receiving sockets (unicast, or multicast with a group join) and
sending sockets."""

from __future__ import annotations

import ipaddress
import socket
import struct
from urllib.parse import urlsplit

import attrs

from radartracker.errors import ConfigurationError

RECEIVE_BUFFER = 8 * 2**20  # bytes asked of the kernel per socket: absorbs bursts while the reader is busy


@attrs.frozen
class Endpoint:
    """An IPv4 UDP address; ``multicast`` when ``host`` is in 224.0.0.0/4."""

    host: str
    port: int

    @property
    def multicast(self) -> bool:
        return ipaddress.IPv4Address(self.host).is_multicast

    def __str__(self) -> str:
        return f"udp://{self.host}:{self.port}"


def parse_endpoint(text: str) -> Endpoint:
    """``udp://HOST:PORT`` → :class:`Endpoint` (HOST an IPv4 address or a resolvable name)."""
    parts = urlsplit(text)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme != "udp" or not parts.hostname or port is None or parts.path not in ("", "/"):
        raise ConfigurationError(f"endpoint {text!r}: expected udp://HOST:PORT")
    try:
        host = socket.gethostbyname(parts.hostname)
    except OSError as exc:
        raise ConfigurationError(f"endpoint {text!r}: cannot resolve {parts.hostname}: {exc}") from None
    return Endpoint(host, port)


def open_receiver(ep: Endpoint, interface: str = "0.0.0.0") -> socket.socket:
    """A non-blocking socket bound to ``ep``; a multicast group is joined on ``interface``. A multicast
    socket is bound to the group's address, not to every address (issue 33: bound to 0.0.0.0 it decoded
    unicast datagrams sent to the port from anywhere), and takes only the groups it joined itself
    (``IP_MULTICAST_ALL`` off, where Linux has it)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER)
        if ep.multicast:
            sock.bind((ep.host, ep.port))
            if hasattr(socket, "IP_MULTICAST_ALL"):
                sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_ALL, 0)
            mreq = struct.pack("4s4s", socket.inet_aton(ep.host), socket.inet_aton(interface))
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)
        else:
            sock.bind((ep.host, ep.port))
    except OSError as exc:
        sock.close()
        raise ConfigurationError(f"cannot listen on {ep}: {exc}") from None
    sock.setblocking(False)
    return sock


def open_sender(ep: Endpoint, ttl: int = 1, interface: str = "0.0.0.0") -> socket.socket:
    """A socket sending to ``ep``. Multicast: time-to-live ``ttl`` (1 stays on the local network),
    sent out of ``interface`` (IP_MULTICAST_IF; 0.0.0.0: the routing table's choice, 127.0.0.1: the
    loopback, with no route needed) and looped back to listeners on this host (IP_MULTICAST_LOOP)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
    try:
        if ep.multicast:
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, ttl)
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton(interface))
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
        sock.connect((ep.host, ep.port))
    except OSError as exc:
        sock.close()
        raise ConfigurationError(f"cannot send to {ep} (interface {interface}): {exc}") from None
    return sock
