#!/usr/bin/env python3
"""A small HTTP/1.1 file server for the remote-store tests, standard library only.

Serves --root on 127.0.0.1 at a free port (written to --port-file once listening): threaded,
keep-alive, GET and HEAD, Range (bytes=a-b, bytes=a-, suffix bytes=-n; 206 + Content-Range, 416 past
the end), 404 for a missing file, 403 for paths containing a --deny substring. With --fault-rate P a
fraction P of the requests whose path contains --fault-paths (default: every path) fail one of the
--faults ways, chosen at random (--seed):
  500       a 500 Internal Server Error
  drop      the headers announce the whole body, half of it is sent, the connection is closed
  stall     no answer for --stall seconds (past the client's timeout), then the connection is closed
  truncate  (Range requests) a 206 whose body is half the range it announces
--fail-always SUBSTR answers 500 to every request whose path contains SUBSTR (a brick that fails for
good). --no-range answers every Range request with 200 and the whole file. The path is percent-decoded
before it is looked up, as real servers do. With --hostile, a path containing one of these words gets
a hostile answer instead of the file (the bad-input corpus's HTTP cases):
  hostile-huge-length    200 announcing a 64 GiB body, then zeros until the client hangs up
  hostile-endless        200 with a chunked body that never ends
  hostile-bad-length     200 with "Content-Length: -5"
  hostile-chunked-garbage 200 chunked, with a chunk size that is not hex
  hostile-long-header    200 with a 300 kB header line
Each request is logged to --log as "METHOD PATH RANGE STATUS FAULT". The server exits by itself after
--max-seconds.
"""
import argparse
import http.server
import os
import random
import re
import socket
import socketserver
import sys
import threading
import time
import urllib.parse


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--root", required=True)
    ap.add_argument("--port-file", required=True)
    ap.add_argument("--log")
    ap.add_argument("--fault-rate", type=float, default=0.0)
    ap.add_argument("--faults", default="500,drop,stall,truncate")
    ap.add_argument("--fault-paths", default="")
    ap.add_argument("--fail-always", default="")
    ap.add_argument("--deny", default="")
    ap.add_argument("--stall", type=float, default=3.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-range", action="store_true")
    ap.add_argument("--max-seconds", type=float, default=600.0)
    ap.add_argument("--hostile", action="store_true")
    a = ap.parse_args()

    root = os.path.realpath(a.root)
    faults = [f for f in a.faults.split(",") if f]
    rng = random.Random(a.seed)
    lock = threading.Lock()
    log = open(a.log, "a", buffering=1) if a.log else None

    def draw(path, ranged):
        if a.fail_always and a.fail_always in path:
            return "always"
        if a.fault_rate <= 0 or (a.fault_paths and a.fault_paths not in path):
            return ""
        with lock:
            if rng.random() >= a.fault_rate:
                return ""
            choices = [f for f in faults if f != "truncate" or ranged]
            return rng.choice(choices) if choices else ""

    class Handler(http.server.BaseHTTPRequestHandler):
        protocol_version = "HTTP/1.1"

        def setup(self):
            super().setup()
            # Headers and body go out in separate writes: without TCP_NODELAY, Nagle's algorithm and
            # the client's delayed ACK add ~40 ms to every keep-alive request.
            self.connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

        def log_message(self, *args):
            pass

        def note(self, rng_text, status, fault):
            if log:
                with lock:
                    log.write("%s %s %s %s %s\n" % (self.command, self.path, rng_text or "-", status, fault or "-"))

        def answer(self, status, body=b"", headers=()):
            self.send_response(status)
            for k, v in headers:
                self.send_header(k, v)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            if self.command != "HEAD":
                self.wfile.write(body)

        def hostile(self, path):
            def raw(text):
                self.wfile.write(text.encode())
                self.wfile.flush()
            self.close_connection = True
            try:
                if "hostile-huge-length" in path:
                    self.note("", 200, "huge-length")
                    raw("HTTP/1.1 200 OK\r\nContent-Length: 68719476736\r\n\r\n")
                    zeros = b"0" * (1 << 20)
                    for _ in range(1 << 16):
                        self.wfile.write(zeros)
                elif "hostile-endless" in path:
                    self.note("", 200, "endless")
                    raw("HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n")
                    chunk = b"100000\r\n" + b"1" * (1 << 20) + b"\r\n"
                    for _ in range(1 << 16):
                        self.wfile.write(chunk)
                elif "hostile-bad-length" in path:
                    self.note("", 200, "bad-length")
                    raw("HTTP/1.1 200 OK\r\nContent-Length: -5\r\n\r\n{}")
                elif "hostile-chunked-garbage" in path:
                    self.note("", 200, "chunked-garbage")
                    raw("HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\n{}\r\n0\r\n\r\n")
                elif "hostile-long-header" in path:
                    self.note("", 200, "long-header")
                    raw("HTTP/1.1 200 OK\r\nX-Junk: " + "a" * 300000 + "\r\nContent-Length: 2\r\n\r\n{}")
                else:
                    return False
            except (BrokenPipeError, ConnectionResetError):
                pass
            return True

        def serve(self):
            path = urllib.parse.unquote(self.path.split("?", 1)[0])
            if a.hostile and self.hostile(path):
                return
            rel = os.path.normpath(path.lstrip("/"))
            file = os.path.realpath(os.path.join(root, rel))
            range_header = self.headers.get("Range", "")
            ranged = bool(range_header) and not a.no_range
            fault = draw(path, ranged)
            if fault == "always" or fault == "500":
                self.note(range_header, 500, fault)
                return self.answer(500, b"injected fault\n")
            if fault == "stall":
                self.note(range_header, 0, fault)
                time.sleep(a.stall)
                self.close_connection = True
                return
            if a.deny and a.deny in path:
                self.note(range_header, 403, "")
                return self.answer(403, b"forbidden\n")
            if not (file == root or file.startswith(root + os.sep)) or not os.path.isfile(file):
                self.note(range_header, 404, "")
                return self.answer(404, b"not found\n")
            with open(file, "rb") as f:
                data = f.read()
            size = len(data)
            status, first, last = 200, 0, size - 1
            if ranged:
                m = re.fullmatch(r"bytes=(\d*)-(\d*)", range_header.strip())
                if not m or (m.group(1) == "" and m.group(2) == ""):
                    self.note(range_header, 416, "")
                    return self.answer(416, b"", [("Content-Range", "bytes */%d" % size)])
                if m.group(1) == "":
                    n = int(m.group(2))
                    first, last = max(0, size - n), size - 1
                else:
                    first = int(m.group(1))
                    last = min(int(m.group(2)), size - 1) if m.group(2) else size - 1
                if first >= size or last < first:
                    self.note(range_header, 416, "")
                    return self.answer(416, b"", [("Content-Range", "bytes */%d" % size)])
                status = 206
            body = data[first:last + 1]
            headers = [("Accept-Ranges", "bytes")]
            if status == 206:
                headers.append(("Content-Range", "bytes %d-%d/%d" % (first, last, size)))
            if fault == "truncate" and status == 206 and len(body) > 1:
                self.note(range_header, status, fault)
                return self.answer(status, body[: len(body) // 2], headers)
            if fault == "drop" and len(body) > 1:
                self.note(range_header, status, fault)
                self.send_response(status)
                for k, v in headers:
                    self.send_header(k, v)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body[: len(body) // 2])
                self.wfile.flush()
                self.close_connection = True
                return
            self.note(range_header, status, "")
            self.answer(status, body, headers)

        def do_GET(self):
            self.serve()

        def do_HEAD(self):
            self.serve()

    class Server(socketserver.ThreadingMixIn, http.server.HTTPServer):
        daemon_threads = True
        allow_reuse_address = True

    server = Server(("127.0.0.1", 0), Handler)
    tmp = a.port_file + ".tmp"
    with open(tmp, "w") as f:
        f.write(str(server.server_address[1]))
    os.replace(tmp, a.port_file)  # the test reads a whole port number or nothing
    timer = threading.Timer(a.max_seconds, server.shutdown)
    timer.daemon = True
    timer.start()
    try:
        server.serve_forever(poll_interval=0.2)
    except KeyboardInterrupt:
        pass
    server.server_close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
