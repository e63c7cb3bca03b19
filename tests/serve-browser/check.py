#!/usr/bin/env python3
"""The live page in a real browser: headless Chromium loads `rollfuse stream --serve`'s page
during a paced virtual-device stream, watches the strip grow and the page told the stream
ended, fails on any console error or uncaught exception, and saves a screenshot.

Standard library only: Chromium is driven over its DevTools protocol (a WebSocket, spoken
here by hand). Exit 0 when the page behaved, 1 with the reason otherwise.

    python3 tests/serve-browser/check.py --rollfuse target/debug/rollfuse \
        --screenshot docs/img/serve-page.png
"""

import argparse
import base64
import json
import os
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
import urllib.request


class WebSocket:
    """A WebSocket client for text frames, enough for the DevTools protocol."""

    def __init__(self, url):
        rest = url.split("://", 1)[1]
        hostport, path = rest.split("/", 1)
        host, port = hostport.rsplit(":", 1)
        self.sock = socket.create_connection((host, int(port)), timeout=10)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall(
            f"GET /{path} HTTP/1.1\r\nHost: {hostport}\r\nUpgrade: websocket\r\n"
            f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
            "Sec-WebSocket-Version: 13\r\n\r\n".encode()
        )
        head = b""
        while b"\r\n\r\n" not in head:
            head += self.sock.recv(1)
        if b" 101 " not in head.split(b"\r\n", 1)[0]:
            raise RuntimeError(f"WebSocket refused: {head!r}")

    def send(self, text):
        data = text.encode()
        mask = os.urandom(4)
        n = len(data)
        if n < 126:
            header = struct.pack("!BB", 0x81, 0x80 | n)
        elif n < 65536:
            header = struct.pack("!BBH", 0x81, 0x80 | 126, n)
        else:
            header = struct.pack("!BBQ", 0x81, 0x80 | 127, n)
        masked = bytes(b ^ mask[i % 4] for i, b in enumerate(data))
        self.sock.sendall(header + mask + masked)

    def _exact(self, n):
        out = b""
        while len(out) < n:
            chunk = self.sock.recv(n - len(out))
            if not chunk:
                raise RuntimeError("DevTools connection closed")
            out += chunk
        return out

    def receive(self, timeout):
        """One text message, or None after `timeout` seconds."""
        self.sock.settimeout(timeout)
        try:
            first = self._exact(2)
        except socket.timeout:
            return None
        self.sock.settimeout(10)
        n = first[1] & 0x7F
        if n == 126:
            n = struct.unpack("!H", self._exact(2))[0]
        elif n == 127:
            n = struct.unpack("!Q", self._exact(8))[0]
        payload = self._exact(n)
        return payload.decode() if first[0] & 0x0F == 1 else ""


class Page:
    """A Chromium tab over DevTools: commands, and the console's errors collected."""

    def __init__(self, ws):
        self.ws, self.next_id, self.errors = ws, 0, []

    def _note(self, msg):
        method, params = msg.get("method"), msg.get("params", {})
        if method == "Runtime.exceptionThrown":
            self.errors.append(json.dumps(params["exceptionDetails"])[:400])
        elif method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
            self.errors.append("console: " + json.dumps(params.get("args"))[:400])
        elif method == "Log.entryAdded" and params["entry"].get("level") == "error":
            self.errors.append("log: " + params["entry"].get("text", "")[:400])

    def call(self, method, **params):
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        deadline = time.time() + 20
        while time.time() < deadline:
            text = self.ws.receive(1.0)
            if not text:
                continue
            msg = json.loads(text)
            if msg.get("id") == self.next_id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            self._note(msg)
        raise RuntimeError(f"{method}: no answer")

    def pump(self, seconds):
        """Takes the events that come within `seconds`."""
        deadline = time.time() + seconds
        while time.time() < deadline:
            text = self.ws.receive(max(0.01, deadline - time.time()))
            if text:
                self._note(json.loads(text))

    def evaluate(self, expression):
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        return result.get("result", {}).get("value")


def start_stream(rollfuse, scene, out_dir, frame_rate, detect, records=None):
    """`rollfuse stream --serve 127.0.0.1:0`, paced (with the detector if `detect`, into
    the inspection records `records` if given); the process and the page's address."""
    # With records, short segments: each is recorded as it lands, so the roll's map is
    # there while the stream runs.
    extra = (["--detect"] if detect else []) + (
        ["--records", records, "--segment-rows", "64"] if records else [])
    proc = subprocess.Popen(
        [rollfuse, "stream", "--device", "sim", "--scene", scene, "--out", out_dir,
         "--frame-rate", str(frame_rate), "--serve", "127.0.0.1:0"] + extra,
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
    )
    line = proc.stdout.readline().strip()
    if not line.startswith("live page: "):
        proc.kill()
        raise RuntimeError(f"rollfuse did not say where it serves: {line!r}")
    return proc, line.removeprefix("live page: ")


def start_chromium(chromium, profile):
    """Headless Chromium with DevTools on a free port; the process and the page's socket."""
    proc = subprocess.Popen(
        [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
         "--window-size=1100,760", "--remote-debugging-port=0", f"--user-data-dir={profile}",
         "about:blank"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    port_file = os.path.join(profile, "DevToolsActivePort")
    deadline = time.time() + 30
    while not os.path.exists(port_file) or os.path.getsize(port_file) == 0:
        if time.time() > deadline or proc.poll() is not None:
            stop_chromium(proc)
            raise RuntimeError("Chromium did not open its DevTools port")
        time.sleep(0.1)
    port = open(port_file).read().split()[0]
    targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list"))
    page = next(t for t in targets if t["type"] == "page")
    return proc, page["webSocketDebuggerUrl"]


def stop_chromium(proc):
    """Ends Chromium and its helper processes (its own process group), and waits for them, so
    none is still writing into the profile when the temporary directory goes."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait(timeout=30)
    deadline = time.time() + 10
    while time.time() < deadline:
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            return
        time.sleep(0.1)


def watch_page(page, url, seconds):
    """Loads the page and samples the rows it shows until the stream ends; the samples,
    whether the detector's table was shown at each, and whether the page saw the end."""
    for domain in ("Runtime", "Log", "Page"):
        page.call(f"{domain}.enable")
    page.call("Page.navigate", url=url)
    samples, tables, ended = [], [], False
    deadline = time.time() + seconds
    while time.time() < deadline:
        page.pump(0.3)
        shown = page.evaluate("Number(document.getElementById('rows').textContent)")
        state = page.evaluate("document.getElementById('state').textContent")
        samples.append(shown)
        tables.append(page.evaluate("!document.getElementById('detector').hidden"))
        if state == "stream ended":
            ended = True
            break
    page.pump(0.5)
    return samples, tables, ended


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rollfuse", required=True)
    ap.add_argument("--chromium", default="chromium")
    ap.add_argument("--scene", default="host/scenes/letters.toml")
    ap.add_argument("--frame-rate", type=float, default=8.0)
    ap.add_argument("--screenshot", required=True)
    ap.add_argument("--detect", action="store_true",
                    help="run the defect detector too, and require its boxes on the page")
    ap.add_argument("--records", action="store_true",
                    help="keep the roll in records too, and require its map on the page")
    args = ap.parse_args()
    # A helper Chromium left behind may still hold its profile; that must not fail the check.
    with tempfile.TemporaryDirectory(ignore_cleanup_errors=True) as tmp:
        # The browser first: however long it takes to start, the stream starts after it,
        # so the page is loaded while the strip grows.
        browser, ws_url = start_chromium(args.chromium, os.path.join(tmp, "profile"))
        stream = None
        try:
            page = Page(WebSocket(ws_url))
            records = os.path.join(tmp, "records.db") if args.records else None
            stream, url = start_stream(args.rollfuse, args.scene, os.path.join(tmp, "out"),
                                       args.frame_rate, args.detect, records)
            samples, tables, ended = watch_page(page, url, seconds=60)
            # The map the page last loaded while streaming (the records are read every
            # 2 s, the page asks every 3 s) stays once the server is gone.
            map_width = page.evaluate(
                "document.getElementById('rollmap').hidden ? 0 : "
                "document.getElementById('rollmap').naturalWidth")
            boxes = page.evaluate("found.boxes.length")
            table_shown = page.evaluate("!document.getElementById('detector').hidden")
            shot = page.call("Page.captureScreenshot", format="png")
            with open(args.screenshot, "wb") as f:
                f.write(base64.b64decode(shot["data"]))
        finally:
            stop_chromium(browser)
            if stream is not None:
                stream.wait(timeout=60)
    print(f"rows shown over time: {samples}")
    # A sample is None while the page is not loaded yet (no element to read).
    samples = [n for n in samples if isinstance(n, (int, float))]
    if not samples:
        print("FAIL: the page never showed its row counter (did it load?)")
        return 1
    grew = any(b > a for a, b in zip(samples, samples[1:]))
    print(f"screenshot: {args.screenshot}")
    if page.errors:
        print("FAIL: console errors:\n  " + "\n  ".join(page.errors))
        return 1
    if not grew or samples[-1] == 0:
        print("FAIL: the strip did not grow on the page")
        return 1
    if not ended:
        print("FAIL: the page was never told the stream ended")
        return 1
    if args.detect:
        print(f"defect boxes on the page: {boxes}")
        if not (boxes and table_shown):
            print("FAIL: the detector's boxes or its table are not on the page")
            return 1
        if any(a and not b for a, b in zip(tables, tables[1:])):
            print(f"FAIL: the detector's table came and went while streaming: {tables}")
            return 1
    elif table_shown:
        print("FAIL: the page shows a detector that does not run")
        return 1
    if args.records:
        print(f"roll map on the page: {map_width} px wide")
        if not map_width:
            print("FAIL: the roll's map never showed on the page")
            return 1
    print("the page showed the strip growing, with no console error")
    return 0


if __name__ == "__main__":
    sys.exit(main())
