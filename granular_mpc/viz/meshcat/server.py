"""The meshcat server as a child process, and a command socket with time-outs.

meshcat 0.3.2's server listens for HTTP/WebSocket on every interface and its command
socket has no time-out (a stuck server blocks the caller forever). :class:`MeshcatServer`
starts the same server module with tornado's ``listen`` bound to 127.0.0.1 and stops the
process itself; :class:`ZmqWindow` talks to it through its own ZMQ ``REQ`` socket, with
send and receive time-outs.
"""

from __future__ import annotations

import os
import selectors
import subprocess
import sys
import tempfile
import threading
import time
import weakref

import umsgpack
import zmq

from ...exceptions import ViewerError
from .backend import package_dir

# The meshcat 0.3.2 server listens for HTTP/WebSocket on every interface (tornado's
# Application.listen(port) without an address). Ours binds 127.0.0.1 only.
_SERVER_CODE = r"""
import sys
import tornado.web
_listen = tornado.web.Application.listen
def _listen_local(self, port, address=None, **kwargs):
    return _listen(self, port, "127.0.0.1", **kwargs)
tornado.web.Application.listen = _listen_local
sys.argv = [sys.argv[0]]
from meshcat.servers.zmqserver import main
main()
"""


class MeshcatServer:
    """A meshcat server subprocess bound to 127.0.0.1 (ZMQ for commands, HTTP for browsers).

    Starts at construction and waits until the server prints its two URLs. The process is
    stopped by :meth:`close`, or when this object is garbage-collected or Python exits.

    Args:
        start_timeout_s: how long to wait for the server's URLs [s].

    Attributes:
        proc: the child process.
        zmq_url: the command socket (``tcp://127.0.0.1:<port>``).
        web_url: the page to open in a browser.

    Raises:
        ViewerError: the server exited at start or did not print its URLs in time.
    """

    def __init__(self, start_timeout_s: float = 20.0) -> None:
        env = dict(os.environ)
        site = str(package_dir().parent)
        env["PYTHONPATH"] = site + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        # stderr goes to an anonymous file: read only to explain a failed start.
        err = tempfile.TemporaryFile()
        self.proc = subprocess.Popen([sys.executable, "-u", "-c", _SERVER_CODE],
                                     stdout=subprocess.PIPE, stderr=err,
                                     stdin=subprocess.DEVNULL, env=env, start_new_session=True)
        self._finalizer = weakref.finalize(self, _stop_process, self.proc, err)
        sel = selectors.DefaultSelector()
        sel.register(self.proc.stdout, selectors.EVENT_READ)
        deadline = time.monotonic() + start_timeout_s
        urls: dict[str, str] = {}
        seen = []
        buf = b""
        try:
            while len(urls) < 2:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise ViewerError("the meshcat server did not start in time",
                                      detail=" | ".join(seen))
                if not sel.select(timeout=left):
                    continue
                chunk = os.read(self.proc.stdout.fileno(), 4096)
                if not chunk:
                    self.proc.wait(timeout=5.0)
                    err.seek(0)
                    tail = err.read()[-2000:].decode("utf-8", "replace")
                    raise ViewerError("the meshcat server exited at start",
                                      detail=f"exit code {self.proc.returncode}; "
                                             + " | ".join(seen + [tail]))
                buf += chunk
                while b"\n" in buf:
                    line, buf = buf.split(b"\n", 1)
                    text = line.decode("utf-8", "replace").strip()
                    seen.append(text)
                    for key in ("zmq_url", "web_url"):
                        if text.startswith(key + "="):
                            urls[key] = text[len(key) + 1:]
        except BaseException:
            self.close()
            self.proc.stdout.close()
            raise
        finally:
            sel.close()
        self.zmq_url = urls["zmq_url"]
        self.web_url = urls["web_url"]
        # Keep reading the server's stdout so that it never blocks on a full pipe.
        threading.Thread(target=_drain, args=(self.proc.stdout,), daemon=True).start()

    @property
    def pid(self) -> int:
        """Process id of the server."""
        return self.proc.pid

    def alive(self) -> bool:
        """True while the server process runs."""
        return self.proc.poll() is None

    def close(self) -> None:
        """Stop the server (SIGTERM, then SIGKILL after 3 s); idempotent."""
        self._finalizer()


def _stop_process(proc, err_file) -> None:
    """Stop our server child (SIGTERM, then SIGKILL after 3 s). Its stdout is closed by
    the drain thread once it reads end-of-file, never under that thread's feet."""
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout=3.0)
        except Exception:
            proc.kill()
            proc.wait()
    err_file.close()


def _drain(stream) -> None:
    """Read and drop a pipe until end-of-file, then close it."""
    try:
        fd = stream.fileno()
        while os.read(fd, 4096):
            pass
    except (OSError, ValueError):
        pass
    finally:
        stream.close()


class ZmqWindow:
    """Connection to the server's command socket, with time-outs (meshcat's has none).

    Plays the part of meshcat's ``ViewerWindow`` for a ``Visualizer(window=...)``.

    Args:
        zmq_url: the server's command socket.
        timeout_s: how long to wait for one send and one reply [s].
    """

    def __init__(self, zmq_url: str, timeout_s: float) -> None:
        self._ctx = zmq.Context.instance()
        self.zmq_url = zmq_url
        self.timeout_ms = max(1, int(1000 * timeout_s))
        self._sock = None
        self.n_sent = 0
        self._connect()

    def _connect(self) -> None:
        if self._sock is not None:
            self._sock.close(linger=0)
        s = self._ctx.socket(zmq.REQ)
        s.setsockopt(zmq.LINGER, 0)
        s.setsockopt(zmq.RCVTIMEO, self.timeout_ms)
        s.setsockopt(zmq.SNDTIMEO, self.timeout_ms)
        s.connect(self.zmq_url)
        self._sock = s

    def request(self, frames: list[bytes]) -> bytes:
        """Send one multipart request and return the reply.

        Raises:
            ViewerError: no reply within the time-out (the socket is reconnected).
        """
        try:
            self._sock.send_multipart(frames)
            reply = self._sock.recv()
        except zmq.Again:
            self._connect()  # a REQ socket that timed out cannot be used again
            raise ViewerError("the meshcat server did not answer",
                              detail=f"no reply within {self.timeout_ms} ms") from None
        return reply

    def send(self, command) -> None:
        """Send one meshcat command (``SetObject``, ``SetTransform`` …)."""
        data = command.lower()
        self.request([data["type"].encode("utf-8"), data["path"].encode("utf-8"),
                      umsgpack.packb(data)])
        self.n_sent += 1

    def get_scene(self) -> str:
        """The server's current scene as a standalone page (meshcat's ``static_html``)."""
        return self.request([b"get_scene"]).decode("utf-8")

    def close(self) -> None:
        """Close the socket (idempotent)."""
        if self._sock is not None:
            self._sock.close(linger=0)
            self._sock = None


__all__ = ["MeshcatServer", "ZmqWindow"]
