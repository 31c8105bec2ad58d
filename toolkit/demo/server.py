"""The web app: Panel's server (Bokeh's, on tornado) with one DemoView per tab, and the rules
that stop it cleanly.

- Each tab (a Bokeh session) gets its own view and render thread; closing the tab ends its
  session after a few seconds (SESSION_SECONDS) and stops its thread. When the last tab has
  been closed for LAST_TAB_GRACE seconds, the server stops too, so nothing is left running.
- Ctrl-C (SIGINT) and SIGTERM stop every render thread after its current pass, then the server.
- It listens on 127.0.0.1 only, unless `host` says otherwise, and accepts page connections
  (WebSockets) only from the address it serves, so another web site open in the browser
  cannot drive it.
"""
import logging
import os
import signal
import socket
import sys
import threading
import webbrowser

import panel as pn
from bokeh.settings import settings as bokeh_settings
from panel.io.resources import LOCAL_DIST
from tornado.ioloop import IOLoop
from tornado.iostream import StreamClosedError
from tornado.websocket import WebSocketClosedError

from toolkit.demo.view import DemoView

SESSION_SECONDS = 2        # a closed tab's session ends this long after its connection closed
LAST_TAB_GRACE = 5         # seconds with no tab before the server stops (a reload opens one again)
STOP_SECONDS = 15          # the longest wait for a render thread's pass before exiting regardless
LOOPBACK = "127.0.0.1"
# A tab's redraws between its closing and the end of its session find no connection: not news.
logging.getLogger("bokeh.server.views.ws").setLevel(logging.ERROR)


def quiet_closed_sockets(loop, context):
    """The event loop's handler of errors nobody collected: a redraw sent to a tab that has just
    closed fails with WebSocketClosedError in a task that Bokeh does not wait for, and asyncio
    would print it with a traceback. Not news (as above); anything else goes to the default."""
    if isinstance(context.get("exception"), (WebSocketClosedError, StreamClosedError)):
        return
    loop.default_exception_handler(context)


def free_port(host):
    """A port nobody listens on now (the OS picks it), for a server that starts right after."""
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def allowed_origins(host, port):
    """Where a page may connect to the server from: the address it serves (and localhost's names)."""
    if host in ("0.0.0.0", "::", ""):
        return ["*"]            # any address of this machine: the --host warning says so
    return sorted({f"{host}:{port}", f"127.0.0.1:{port}", f"localhost:{port}"})


def keep_styles_local(doc):
    """Panel points a model's style sheets (loading.css, a widget's own) at this server once it has
    made the session's page (the document's `dist_url`, which it sets then); a model changed before
    that, as a second tab's was while the first one rendered, got Panel's CDN instead, which an
    offline page cannot load. Set from the session's start, as Panel sets it for the page."""
    if doc is not None and "dist_url" not in doc._template_variables:
        doc._template_variables["dist_url"] = f"{pn.state.rel_path}/{LOCAL_DIST}" if pn.state.rel_path else LOCAL_DIST


class DemoServer:
    """Serves DemoView(scenes, settings, device) on host:port; run() blocks until it stops."""

    def __init__(self, scenes, settings, device=None, host=LOOPBACK, port=None):
        self.scenes, self.settings, self.device = scenes, settings, device
        self.host = host
        self.port = port or free_port(host)
        self.views = set()
        self.stopped_views = []            # closed tabs' views: their threads are waited for at exit
        self.ever_opened = False
        self.loop = IOLoop.current()
        self.loop.asyncio_loop.set_exception_handler(quiet_closed_sockets)
        # Bokeh's and Panel's files come from this server, never from a CDN: the page works offline,
        # and a style sheet that Panel makes in a redraw (loading.css, where Bokeh's own default,
        # "cdn", applies) cannot fail to load.
        bokeh_settings.resources.set_value("server")
        self.server = pn.serve({"/": self.new_tab}, port=self.port, address=host,
                               websocket_origin=allowed_origins(host, self.port), show=False, start=False,
                               title="SIMD efficiency, live", loop=self.loop, verbose=False,
                               check_unused_sessions_milliseconds=1000,
                               unused_session_lifetime_milliseconds=SESSION_SECONDS * 1000)

    @property
    def url(self):
        shown = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{shown}:{self.port}/"

    def new_tab(self):
        """A session's page: its own view and render thread, stopped with the session."""
        keep_styles_local(pn.state.curdoc)
        view = DemoView(self.scenes, self.settings, self.device)
        # Redraws start once the browser has the page: a redraw that adds figures (the first
        # frame's) sent before the page's document reached the browser referred to models the
        # browser did not know yet ("reference ... isn't known"), and that tab never showed an image.
        pn.state.onload(view.start)
        self.views.add(view)
        self.ever_opened = True
        pn.state.on_session_destroyed(lambda context: self.tab_closed(view))
        return view.panel

    def tab_closed(self, view):
        view.stop(timeout=0)               # the thread ends after its pass; stop() below waits for it
        self.views.discard(view)
        self.stopped_views.append(view)
        if not self.views:
            self.loop.call_later(LAST_TAB_GRACE, self._stop_if_no_tab)

    def _stop_if_no_tab(self):
        if not self.views and self.ever_opened:
            print("the last tab was closed: stopping", file=sys.stderr, flush=True)
            self.stop()

    def stop(self, *_):
        """Stop serving (from the loop's thread); run() then stops the render threads."""
        self.server.stop()
        self.loop.stop()

    def run(self, open_browser=True):
        """Serve until Ctrl-C, SIGTERM or the last tab's closing; returns 0, or 1 if a render
        thread would not stop (the process then exits at once, leaving nothing behind)."""
        for number in (signal.SIGINT, signal.SIGTERM):
            signal.signal(number, lambda *_: self.loop.add_callback_from_signal(self.stop))
        self.server.start()
        print(f"serving the demo at {self.url} (Ctrl-C stops it)", flush=True)
        if open_browser:
            threading.Thread(target=webbrowser.open, args=(self.url,), daemon=True).start()
        try:
            self.loop.start()
        finally:
            clean = all(view.stop(timeout=STOP_SECONDS) for view in [*self.views, *self.stopped_views])
        if not clean:
            print("error: a render thread did not stop; exiting anyway", file=sys.stderr, flush=True)
            sys.stderr.flush()
            os._exit(1)
        return 0
