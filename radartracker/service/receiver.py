"""The socket reader: datagrams from every listening socket into one bounded queue.

The reader never waits for the tracker: when the queue is full the datagram is dropped and counted
(``datagrams_dropped_queue_full``), so a slow tracker costs data, never the kernel's buffers
overflowing unseen. Each queued entry is ``(receive time (s since 1970), monotonic receive time,
listening endpoint, payload)``.
"""

from __future__ import annotations

import os
import queue
import selectors
import socket
import threading
import time
from collections import Counter

from radartracker.service.endpoints import Endpoint

MAX_DATAGRAM = 65_535
SO_RXQ_OVFL = getattr(socket, "SO_RXQ_OVFL", 40)  # Linux: each datagram carries the socket's drop count


class DatagramQueue(queue.Queue):
    """The queue between the receiver and the tracker: (received, received_mono, endpoint, payload)
    entries, bounded in entries (``maxsize``) and in payload bytes (``max_bytes``): 50 000 datagrams of
    64 kB held 3.5 GB (issue 33). A put beyond either bound raises :class:`queue.Full`. One thread
    puts (the receiver) and takes only shrink the queue, so the byte check before the put holds."""

    def __init__(self, maxsize: int, max_bytes: int) -> None:
        super().__init__(maxsize)
        self.max_bytes, self.bytes = max_bytes, 0

    def _put(self, item: tuple) -> None:  # under the queue's lock
        super()._put(item)
        self.bytes += len(item[3])

    def _get(self) -> tuple:  # under the queue's lock
        item = super()._get()
        self.bytes -= len(item[3])
        return item

    def put_nowait(self, item: tuple) -> None:
        with self.mutex:
            if self.bytes + len(item[3]) > self.max_bytes:
                raise queue.Full
        super().put_nowait(item)


class Receiver(threading.Thread):
    """Reads every socket until :meth:`stop`; counts datagrams received and dropped.

    Drops are counted where they happen: ``datagrams_dropped_queue_full`` and, when only some senders are
    allowed (``allow``: their IPv4 addresses), ``datagrams_refused_sender`` here, and
    ``datagrams_dropped_kernel`` — datagrams the kernel discarded because the socket buffer was
    full — from the counter Linux attaches to each datagram (``SO_RXQ_OVFL``).
    """

    def __init__(self, sockets: dict[Endpoint, socket.socket], out: queue.Queue, allow: frozenset[str] = frozenset()) -> None:
        super().__init__(name="radartracker-receiver", daemon=True)
        self.sockets, self.out, self.allow = sockets, out, allow
        self.counts: Counter[str] = Counter()
        self._halt = threading.Event()
        self._cmsg = socket.CMSG_SPACE(4)
        self._kernel_drops: dict[Endpoint, int] = {}

    def stop(self) -> None:
        """Stop reading (returns at once; :meth:`join` waits for the thread)."""
        self._halt.set()

    def run(self) -> None:
        sel = selectors.DefaultSelector()
        for ep, sock in self.sockets.items():
            try:
                sock.setsockopt(socket.SOL_SOCKET, SO_RXQ_OVFL, 1)
            except OSError:  # not Linux: kernel drops are not visible
                pass
            sel.register(sock, selectors.EVENT_READ, ep)
        try:
            while not self._halt.is_set():
                for key, _ in sel.select(timeout=0.1):
                    self._drain(key.fileobj, key.data)
        finally:
            sel.close()

    def _drain(self, sock: socket.socket, ep: Endpoint) -> None:
        while True:
            try:
                data, anc, _, sender = sock.recvmsg(MAX_DATAGRAM, self._cmsg)
            except (BlockingIOError, InterruptedError):
                return
            self._kernel_count(ep, anc)
            self.counts["datagrams_received"] += 1
            if self.allow and sender[0] not in self.allow:
                self.counts["datagrams_refused_sender"] += 1
                continue
            entry = (time.time(), time.monotonic(), ep, data)
            try:
                self.out.put_nowait(entry)
            except queue.Full:
                self.counts["datagrams_dropped_queue_full"] += 1

    def _kernel_count(self, ep: Endpoint, anc: list) -> None:
        for level, kind, value in anc:
            if level == socket.SOL_SOCKET and kind == SO_RXQ_OVFL and len(value) >= 4:
                self._kernel_dropped(ep, int.from_bytes(value[:4], "little"))

    def _kernel_dropped(self, ep: Endpoint, n: int) -> None:
        """The kernel has dropped ``n`` datagrams on ``ep``'s socket so far."""
        self._kernel_drops[ep] = n
        self.counts["datagrams_dropped_kernel"] = sum(self._kernel_drops.values())

    def discard_unread(self) -> int:
        """After :meth:`stop` and :meth:`join`: read what is still in the sockets' buffers and return how many
        datagrams there were, so that a stop counts them (dropped at the stop) instead of losing them unseen."""
        n = 0
        for ep, sock in self.sockets.items():
            while True:
                try:
                    _, anc, _, _ = sock.recvmsg(MAX_DATAGRAM, self._cmsg)
                except OSError:  # BlockingIOError: the buffer is empty
                    break
                self._kernel_count(ep, anc)
                n += 1
            late = kernel_drops(sock)  # drops after the last datagram queued are attached to none
            if late is not None and late > self._kernel_drops.get(ep, 0):
                self._kernel_dropped(ep, late)
        return n


def kernel_drops(sock: socket.socket) -> int | None:
    """The datagrams the kernel dropped on ``sock`` so far (Linux: the ``drops`` column of /proc/net/udp
    for the socket's inode), or None where that is not available."""
    try:
        inode = str(os.fstat(sock.fileno()).st_ino)
        for table in ("/proc/net/udp", "/proc/net/udp6"):
            with open(table, encoding="ascii") as f:
                for line in f:
                    fields = line.split()
                    if len(fields) > 12 and fields[9] == inode:
                        return int(fields[-1])
    except (OSError, ValueError):
        return None
    return None
