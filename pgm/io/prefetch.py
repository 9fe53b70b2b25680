"""Reading ahead on a thread of its own: a frame source decodes the next frames while the
tracker works on this one (decoding releases the GIL), without losing an error or
leaving a thread behind."""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator

__all__ = ["read_ahead"]

_DONE = object()


def read_ahead(items: Iterator, ahead: int) -> Iterator:
    """``items`` produced by a thread of their own, at most ``ahead`` of them made before
    the consumer asks (one waiting in the thread, the others queued); an exception in the
    producer is raised to the consumer where it happened, and a consumer that stops early
    stops the producer (which then closes ``items``, releasing what it holds)."""
    q: queue.Queue = queue.Queue(maxsize=max(1, ahead - 1))
    stop = threading.Event()

    def produce() -> None:
        try:
            for item in items:
                while not stop.is_set():
                    try:
                        q.put((item, None), timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if stop.is_set():
                    return
            q.put((_DONE, None))
        except BaseException as exc:  # handed to the consumer, raised there
            q.put((_DONE, exc))
        finally:
            items.close()

    thread = threading.Thread(target=produce, name="pgm-decode-video", daemon=True)
    thread.start()
    try:
        while True:
            item, exc = q.get()
            if exc is not None:
                raise exc
            if item is _DONE:
                return
            yield item
    finally:
        stop.set()
        while thread.is_alive():  # let a producer blocked on a full queue see the stop
            try:
                q.get(timeout=0.05)
            except queue.Empty:
                pass
        thread.join()
