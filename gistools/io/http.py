"""Byte ranges of files served over HTTP(S), as object storage serves them: the network client of the point clouds
read from a service (EPT, COPC; gistools.io.area).

Written on urllib3 (pooled connections reused across requests, redirects, TLS with the system's certificates or a
given CA bundle); what urllib3 leaves to its caller is here: every body is checked against the bytes asked for (a
short or over-long body is retried, never taken as data), 5xx / 429 answers, timeouts and reset connections are
retried with exponential backoff, and a request that cannot succeed (404, 403, a redirect loop) is one line naming the
URL. A stop (Ctrl-C, QGIS's Cancel through ``progress``) acts between requests.
"""

from __future__ import annotations

import io
import os
import threading
import time

from ..errors import DataFileError
from ..progress import check_interrupt

RETRY_STATUS = (429, 500, 502, 503, 504)


CA_VARIABLES = ("SSL_CERT_FILE", "REQUESTS_CA_BUNDLE", "CURL_CA_BUNDLE")  # as requests and curl read them


def is_url(text) -> bool:
    """Whether ``text`` names a file served over HTTP(S)."""
    return isinstance(text, str) and text.lower().startswith(("http://", "https://"))


class RangeClient:
    """GETs of whole files and byte ranges over reused connections.

    Parameters
    ----------
    timeout : float
        Seconds to connect, and between two reads of a body.
    retries : int
        Attempts after the first for a request that failed in a way another attempt may not (5xx, 429, a timeout, a
        reset connection, a body of the wrong length).
    backoff : float
        Seconds before the first retry, doubled after each (at most 30 s).
    ca_bundle : str, optional
        A file of CA certificates for HTTPS; None: the one ``SSL_CERT_FILE``, ``REQUESTS_CA_BUNDLE`` or
        ``CURL_CA_BUNDLE`` names, else the system's.
    connections : int
        Connections kept open to one host (and requests in flight at once).

    Examples
    --------
    >>> client = RangeClient(retries=3)
    >>> client.bytes_fetched
    0
    """

    def __init__(self, *, timeout: float = 30.0, retries: int = 6, backoff: float = 0.5, ca_bundle: str | None = None,
                 connections: int = 8):
        import urllib3

        self._urllib3 = urllib3
        self.retries, self.backoff = int(retries), float(backoff)
        ca_bundle = ca_bundle or next((os.environ[v] for v in CA_VARIABLES if os.environ.get(v)), None)
        options = {"ca_certs": ca_bundle} if ca_bundle else {}
        self._pool = urllib3.PoolManager(num_pools=8, maxsize=connections, block=True,
                                         timeout=urllib3.Timeout(connect=timeout, read=timeout), **options)
        self._lock = threading.Lock()
        self.bytes_fetched = 0
        self.requests = 0
        self.retried = 0

    def get(self, url: str, start: int | None = None, length: int | None = None) -> bytes:
        """The bytes of ``url`` (``start`` and ``length``: one range of it; a range past the end of the file is cut
        at its end). DataFileError naming the URL when the server cannot give them."""
        return self.fetch(url, start, length)[0]

    def size(self, url: str) -> int:
        """The length of the file at ``url`` in bytes (from a one-byte range's answer)."""
        total = self.fetch(url, 0, 1)[1]
        if total is None:
            raise DataFileError("the server does not say the file's length", path=url,
                                hint="Serve the file from storage that answers byte ranges with its length")
        return total

    def fetch(self, url: str, start: int | None = None, length: int | None = None) -> tuple[bytes, int | None]:
        """(the bytes, as ``get``; the file's whole length where the answer says it, else None)."""
        delay, last = self.backoff, ""
        for attempt in range(self.retries + 1):
            check_interrupt()
            if attempt:
                with self._lock:
                    self.retried += 1
                time.sleep(min(delay, 30.0))
                delay *= 2
            try:
                return self._get_once(url, start, length)
            except _Retry as err:
                last = str(err)
        raise DataFileError(f"no complete answer after {self.retries + 1} tries ({last})", path=url,
                            hint="Check the network and the server, then run the command again: what was fetched is "
                                 "kept")

    def _get_once(self, url, start, length) -> bytes:
        urllib3 = self._urllib3
        headers = {} if start is None else {"Range": f"bytes={start}-{start + length - 1}"}
        try:
            response = self._pool.request("GET", url, headers=headers, preload_content=True,
                                          retries=urllib3.Retry(total=None, connect=0, read=0, status=0, other=0,
                                                                redirect=5, raise_on_redirect=True))
        except urllib3.exceptions.MaxRetryError as err:
            if "redirect" in str(err.reason).lower():
                raise DataFileError("the server redirects in a loop (more than 5 redirects)", path=url,
                                    hint="Check the URL") from None
            raise _Retry(_reason(err.reason)) from None
        except (urllib3.exceptions.HTTPError, OSError) as err:
            raise _Retry(_reason(err)) from None
        data = response.data
        with self._lock:
            self.requests += 1
            self.bytes_fetched += len(data)
        if response.status in RETRY_STATUS:
            raise _Retry(f"HTTP {response.status}")
        if response.status >= 400:
            what = {404: "not found", 403: "access refused", 401: "needs a login", 410: "gone"}.get(response.status,
                                                                                                  "refused")
            raise DataFileError(f"{what} (HTTP {response.status})", path=url, hint="Check the URL")
        return _checked(url, response, data, start, length)


class _Retry(Exception):
    """A failure another attempt may not meet."""


def _reason(err) -> str:
    text = " ".join(str(err).split())
    return f"{type(err).__name__}: {text[:160]}"


def _checked(url, response, data: bytes, start, length) -> tuple[bytes, int | None]:
    """(the body of a request, the file's length), the body checked against what was asked: a whole file against
    Content-Length, a range against Content-Range; a body of another length is retried."""
    declared = response.headers.get("Content-Length")
    if start is None or response.status == 200:  # a whole file (or a server that ignored the range)
        if declared is not None and int(declared) != len(data):
            raise _Retry(f"a body of {len(data):,} bytes where the server announced {int(declared):,}")
        return (data if start is None else data[start:start + length]), len(data)
    if response.status != 206:
        raise DataFileError(f"answered HTTP {response.status} to a byte range", path=url,
                            hint="The server must serve byte ranges (object storage and nginx do)")
    first, last, total = _content_range(url, response.headers.get("Content-Range"))
    expected = min(length, total - start) if total is not None else length
    if first != start or last - first + 1 != expected or len(data) != expected:
        raise _Retry(f"bytes {first}-{last} ({len(data):,} received) where {start}-{start + expected - 1} were asked")
    return data, total


def _content_range(url, header) -> tuple[int, int, int | None]:
    try:
        unit, _, rest = header.partition(" ")
        span, _, total = rest.partition("/")
        first, _, last = span.partition("-")
        assert unit == "bytes"
        return int(first), int(last), None if total == "*" else int(total)
    except (AttributeError, AssertionError, ValueError):
        raise _Retry(f"a byte range answered without a valid Content-Range ({header!r})") from None


class RangeFile(io.RawIOBase):
    """A file served over HTTP(S), read as a local one (``seek``, ``read``): each read is one range request. Wrap it
    in ``io.BufferedReader`` where a reader makes many small reads (a LAS header).

    Parameters
    ----------
    client : RangeClient
        The client that fetches the ranges (and counts them).
    url : str
        The file's URL.

    Examples
    --------
    >>> RangeFile.__mro__[1].__name__
    'RawIOBase'
    """

    def __init__(self, client: RangeClient, url: str):
        super().__init__()
        self.client, self.url, self._pos = client, url, 0
        self._size = None

    @property
    def size(self) -> int:
        """The file's length in bytes."""
        if self._size is None:
            self._size = self.client.size(self.url)
        return self._size

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def tell(self) -> int:
        return self._pos

    def seek(self, offset: int, whence: int = io.SEEK_SET) -> int:
        base = {io.SEEK_SET: 0, io.SEEK_CUR: self._pos, io.SEEK_END: self.size}[whence]
        self._pos = max(0, base + offset)
        return self._pos

    def readinto(self, buffer) -> int:
        want = min(len(buffer), max(self.size - self._pos, 0))
        if want <= 0:
            return 0
        data = self.client.get(self.url, self._pos, want)
        buffer[:len(data)] = data
        self._pos += len(data)
        return len(data)
