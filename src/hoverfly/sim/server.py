"""`hoverfly sim`: the simulator in real time with its serial ports served over TCP on 127.0.0.1.

Takes an airframe, two TCP port numbers and an optional storage file; gives a running simulated
flight controller whose CLI + MSP port (default 5761, as Betaflight's SITL) and seed-001
maintenance port (5762) accept one TCP client each. The sockets are non-blocking and polled by
the flight core's links task (core/links/task.py, at serial_update_hz) through the sim board's serial
seam, so a client that connects, floods, stops reading or disconnects never stalls the flight loop:
a newer connection replaces an older one, and a disconnect or a replacement ends that port's
session (the links task sees a read of -1 before the next client's first byte); replies a client
does not read are dropped past OUT_LIMIT bytes (counted). The parameter image is the `--storage`
file, written in place (core/config/storage.py's two slots make a cut write harmless). MSP_REBOOT
restarts the simulated controller as a board would: a new flight from the stored parameters, the
craft back on the ground, the TCP listeners and their clients kept.
"""

import socket

from hoverfly.core.board import SERIAL_CONFIG, SERIAL_MAINT
from hoverfly.core.config.storage import Storage
from hoverfly.core.links.task import attach
from hoverfly.errors import UserError

HOST = "127.0.0.1"
DEFAULT_MSP_PORT = 5761
DEFAULT_MAINT_PORT = 5762
OUT_LIMIT = 256 * 1024  # reply bytes held for a slow client before new ones are dropped
_FOREVER_S = 10 * 365 * 24 * 3600.0


class TcpPorts:
    """Listening sockets on 127.0.0.1, one client each, all non-blocking."""

    def __init__(self, ports, host=HOST):
        self.listeners = {}
        self.clients = {}
        self.out = {}
        self.gone = {}
        self.accepted = 0
        self.dropped_bytes = 0
        for pid, number in ports.items():
            s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                s.bind((host, number))
            except OSError as exc:
                s.close()
                self.close()
                raise UserError("cannot serve on %s:%d: %s" % (host, number, exc.strerror or exc)) from None
            s.listen(2)
            s.setblocking(False)
            self.listeners[pid] = s
            self.clients[pid] = None
            self.out[pid] = bytearray()
            self.gone[pid] = False

    def address(self, pid):
        return self.listeners[pid].getsockname()

    def _accept(self, pid):
        try:
            conn, _ = self.listeners[pid].accept()
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            return
        conn.setblocking(False)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        if self.clients[pid] is not None:
            self._drop(pid)  # the newer client wins; read() reports the old one gone first
        self.clients[pid] = conn
        self.accepted += 1

    def _drop(self, pid):
        c = self.clients[pid]
        if c is not None:
            try:
                c.close()
            except OSError:
                pass
        self.clients[pid] = None
        self.out[pid] = bytearray()
        self.gone[pid] = True

    def read(self, pid, buf):
        """Bytes from the port's client into buf: their count, 0 for none, or -1 once for a client that
        went away or was replaced, before any byte of the next one (its session must close first)."""
        self._accept(pid)
        if self.gone[pid]:
            self.gone[pid] = False
            return -1
        self._flush(pid)
        c = self.clients[pid]
        if c is None:
            return 0
        try:
            n = c.recv_into(buf)
        except (BlockingIOError, InterruptedError):
            return 0
        except OSError:
            n = 0
        if n == 0:
            self._drop(pid)
            self.gone[pid] = False
            return -1
        return n

    def write(self, pid, data, n=-1):
        if n < 0:
            n = len(data)
        if self.clients.get(pid) is None:
            return 0
        out = self.out[pid]
        room = OUT_LIMIT - len(out)
        take = n if n <= room else max(0, room)
        out += bytes(data[:take])
        self.dropped_bytes += n - take
        self._flush(pid)
        return take

    def _flush(self, pid):
        c = self.clients[pid]
        out = self.out[pid]
        if c is None or not out:
            return
        try:
            sent = c.send(out)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            self._drop(pid)
            return
        del out[:sent]

    def close(self):
        for pid in list(self.listeners):
            if self.clients.get(pid) is not None:
                self._drop(pid)
            self.listeners[pid].close()
        self.listeners = {}


class SimServer:
    """A real-time SimRun with storage and the TCP ports wired to its board."""

    def __init__(self, airframe="5inch", msp_port=DEFAULT_MSP_PORT, maint_port=DEFAULT_MAINT_PORT,
                 storage_path=None, duration_s=None, seed=1, mode="angle", log_path=None, overrides=()):
        if duration_s is not None and not (0 < duration_s <= _FOREVER_S):
            raise UserError("--duration must be more than 0 s")
        self._boot_args = (airframe, seed, mode, log_path, storage_path,
                           duration_s if duration_s is not None else _FOREVER_S, tuple(overrides))
        self.ports = None
        self._boot()
        self.ports = TcpPorts({SERIAL_CONFIG: msp_port, SERIAL_MAINT: maint_port})
        self.run.board.serial = self.ports
        self.stop_requested = False
        self.reboot_requested = False
        self.reboots = 0
        self.result = None

    def _boot(self):
        """Build the run, load the stored parameters and attach the links: at start and at each reboot."""
        from hoverfly.sim.runner import SimRun

        airframe, seed, mode, log_path, storage_path, duration_s, overrides = self._boot_args
        scenario = {"name": "sim", "duration_s": 3600.0, "mode": mode, "events": [], "params": {}}
        self.run = SimRun(airframe, scenario, seed, (), 3600.0, realtime=True, log_path=log_path)
        self.run.duration_s = duration_s
        board = self.run.board
        board.storage_path = storage_path
        board.serial = self.ports
        self.storage = Storage(board)
        # The simulator is flown from the ground station's gamepad over the maintenance port (issue 24):
        # the seed-001 radio override is on here by default, before the stored set (which may turn it off).
        self.run.params.set("maint_override", 1)
        self.storage_status = self.storage.load(self.run.params)
        for name, value in overrides:  # over the stored set, as `hoverfly fly --set` (not saved)
            err = self.run.params.set(name, value)
            if err:
                raise UserError(err)
        self.flight = self.run.flight
        self.flight.storage = self.storage
        self.links = attach(self.flight, self.storage)  # after the load: serial_update_hz is a reboot parameter
        self.links.config.msp.on_reboot = self._reboot
        self._chained = self.run.on_step
        self.run.on_step = self._on_step

    def _reboot(self):
        # Called by the MSP server once the reply is written: the restart happens between two passes.
        self.reboot_requested = True

    def describe(self):
        msp_addr = self.ports.address(SERIAL_CONFIG)
        maint_addr = self.ports.address(SERIAL_MAINT)
        storage = self.run.board.storage_path
        return ("hoverfly sim: %s, CLI+MSP on %s:%d, maintenance on %s:%d, storage %s"
                % (self.run.airframe["name"], msp_addr[0], msp_addr[1], maint_addr[0], maint_addr[1],
                   "%s (%s)" % (storage, self.storage.summary()) if storage else "none (not saved)"))

    def _on_step(self, run):
        if self._chained is not None:
            self._chained(run)
        if self.stop_requested:
            raise _Stop()
        if self.reboot_requested:
            raise _Reboot()

    def serve(self):
        """Run until the duration ends, stop() is called or Ctrl-C; returns the flight summary.
        A reboot (MSP_REBOOT) ends the run and starts a new one from storage on the same ports."""
        try:
            while True:
                try:
                    self.result = self.run.run()
                    break
                except _Reboot:
                    self.reboot_requested = False
                    self.reboots += 1
                    self._boot()
        except _Stop:
            pass
        finally:
            self.ports.close()
        return self.result

    def stop(self):
        self.stop_requested = True


class _Stop(Exception):
    pass


class _Reboot(Exception):
    pass
