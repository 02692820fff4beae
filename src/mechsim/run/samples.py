"""The output samples of a run (`mechsim.run.loop`): recorded into one growing array, checked
finite as they come, and handed to the result without a copy."""

from __future__ import annotations

import os

import numpy as np

# What a formulation raises when a run cannot go on: the run stops with its partial result.
FAILURES = (ArithmeticError, ValueError, np.linalg.LinAlgError, RuntimeError)
# A driver moving faster than this (rad/s or m/s) is named where a run fails.
DRIVER_RATE_LIMIT = 1e8
# Output samples inside one step are interpolated and solved for this many at a time.
CHUNK = 1024


class NonFiniteState(RuntimeError):
    """The motion became infinite or NaN: the run stops there with its partial result.
    `drivers`: what its message says of the drivers that caused it ("" where none did)."""

    def __init__(self, message: str, drivers: str = ""):
        super().__init__(message)
        self.drivers = drivers


def check_finite(problem, t, q, v) -> None:
    """NonFiniteState where q or v holds an infinite or NaN value, naming the coordinate
    and, where one is the cause, the driver whose prescribed motion is not finite there."""
    for name, x in (("position", q), ("velocity", v)):
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            break
    else:
        return
    drivers = troubled_drivers(problem, (t,))
    raise NonFiniteState(f"the motion became non-finite at t = {t:.9g} ({name} of "
                         f"'{problem.coordinate_names[bad[0]]}' = {x[bad[0]]}){drivers}",
                         drivers)


def troubled_drivers(problem, times) -> str:
    """"; driver 'd' …" for each driver whose law at one of `times` is undefined, not finite
    (or beyond 1e100) or changing faster than `DRIVER_RATE_LIMIT`: the likely cause of a
    failed run; "" where there is none."""
    out = []
    for driver, law in problem.driver_laws:
        for t in times:
            dt = 1e-9 * max(1.0, abs(t))
            try:
                value, ahead = law.value(t=t), law.value(t=t + dt)
            except (ArithmeticError, ValueError) as exc:
                out.append(f"driver '{driver}' prescribes {law.text}, undefined at "
                           f"t ≈ {t:.9g} ({exc})")
                break
            if not (abs(value) < 1e100 and abs(ahead) < 1e100):
                out.append(f"driver '{driver}' prescribes {law.text} = {value:.3g} at "
                           f"t = {t:.9g}")
                break
            if abs(ahead - value) > DRIVER_RATE_LIMIT * dt:
                out.append(f"driver '{driver}' prescribes {law.text}, changing at "
                           f"{(ahead - value) / dt:.3g}/s at t = {t:.9g}")
                break
    return "".join(f"; {o}" for o in out)


def fastest_motion(problem, t, v) -> str:
    """"; fastest: …" naming the coordinate moving fastest in v at t and each driver's rate
    there: where a run's motion ran away (`mechsim.run.runaway.Runaway`)."""
    k = int(np.argmax(np.abs(v)))
    out = [f"fastest: {problem.coordinate_names[k]} at {v[k]:.3g}/s"]
    for driver, law in problem.driver_laws:
        dt = 1e-9 * max(1.0, abs(t))
        try:
            rate = (law.value(t=t + dt) - law.value(t=t)) / dt
        except (ArithmeticError, ValueError):
            continue
        out.append(f"driver '{driver}' prescribes {law.text}, moving at {rate:.3g}/s there")
    return "".join(f"; {o}" for o in out)


class Rows:
    """Rows of `width` numbers in one preallocated array, grown in place (by a quarter) as
    rows come and trimmed in place when handed over: a run's memory is its samples' plus a
    quarter at most, never a list of small arrays or a copy of the whole. `count` rows in
    all; the ones in memory start at global index `first` (0 here; see `DiskRows`)."""

    def __init__(self, width, capacity):
        self.data = np.empty((max(capacity, 1), width))
        self.held, self.first = 0, 0

    @property
    def count(self) -> int:
        return self.first + self.held

    @property
    def rows(self):
        return self.data[:self.held]

    def since(self, k):
        """The rows from global index k on (they are in memory: recorded in this step)."""
        return self.data[k - self.first:self.held]

    def room(self, k=1) -> None:
        if self.held + k > len(self.data):
            self.data.resize((max(self.held + k, int(1.25 * len(self.data)) + 16),
                              self.data.shape[1]), refcheck=False)

    def append(self, row) -> None:
        self.room()
        self.data[self.held] = row
        self.held += 1

    def extend(self, rows) -> None:
        rows = np.asarray(rows, float).reshape(-1, self.data.shape[1])
        self.room(len(rows))
        self.data[self.held:self.held + len(rows)] = rows
        self.held += len(rows)

    def flush(self) -> None:
        """Between steps: nothing to do for rows kept in memory."""

    def take(self) -> np.ndarray:
        """The rows as one array of exactly their size (the buffer itself, trimmed)."""
        self.data.resize((self.held, self.data.shape[1]), refcheck=False)
        return self.data


class DiskRows(Rows):
    """`Rows` streamed to the raw float64 file `name` (row-major) of `directory` (a
    `mechsim.files.OutputDirectory`) a chunk at a time: between steps, once more than
    `chunk` rows are held, all but the last go to the file (the last stays, for whoever
    reads the latest sample). `take()` writes the rest and returns the file as a read-only
    memory map of exactly `count` rows: memory for a chunk, not the run. The file is a new
    one (an earlier file of that name is unlinked, so a memory map of it keeps its data).

    Where writing fails (a full disk), `failure` holds the error, the file keeps its whole
    rows, and the rows from then on stay in memory: `take()` returns them all, in memory."""

    def __init__(self, width, directory, name, chunk=4096):
        super().__init__(width, chunk)
        self.directory, self.name, self.chunk = directory, name, chunk
        self.file = directory.new_file(name)
        self.on_disk = 0
        self.failure: OSError | None = None

    def _write(self, k) -> None:
        """The first k rows held to the file (none once writing has failed)."""
        if self.failure is not None or not k:
            return
        try:
            self.file.write(self.data[:k].tobytes())
            self.file.flush()
        except OSError as exc:
            self.failure = exc
            self._keep_whole_rows()
            return
        self.on_disk += k
        self.data[:self.held - k] = self.data[k:self.held]
        self.first, self.held = self.first + k, self.held - k

    def _keep_whole_rows(self) -> None:
        try:
            os.ftruncate(self.file.fileno(), self.on_disk * self.data.shape[1] * 8)
        except (OSError, ValueError):
            pass

    def flush(self) -> None:
        if self.held > self.chunk:
            self._write(self.held - 1)

    def take(self) -> np.ndarray:
        self._write(self.held)
        try:
            self.file.close()
        except OSError as exc:
            self.failure = self.failure or exc
        width = self.data.shape[1]
        if not self.count or not width:
            return np.zeros((self.count, width))
        on_disk = self.directory.map(self.name, (self.on_disk, width)) if self.on_disk else \
            np.zeros((0, width))
        if not self.held:
            return on_disk
        return np.concatenate([on_disk, self.data[:self.held]])


class Recorder:
    """The output samples of a run: times `t`, positions `q`, velocities `v` (rows), and the
    work of each of `channels` at the first `work.count` of them (`Rows`). `ts` is the output
    grid (None: a sample at every accepted step), which sizes the arrays at once; `next`
    the index of its next sample. Samples pass `check_finite` as they are recorded."""

    def __init__(self, problem, ts, channels=(), stream=None, extras=None, width=0):
        self.problem, self.ts, self.next = problem, ts, 0
        self.n = problem.n
        capacity = len(ts) if ts is not None else 256
        # What the formulation carries besides the motion (its sensitivities), `width`
        # numbers per sample from `extras(times, Y, Q, V)` (rows of the integrator's state
        # and the samples as recorded), in memory also where the samples are streamed.
        self.extras = extras
        self.extra = Rows(width, capacity if extras is not None else 0)
        if stream is not None:       # an OutputDirectory: samples.bin, work.bin
            self.samples = DiskRows(1 + 2 * problem.n, stream, "samples.bin")
            self.work = DiskRows(len(channels), stream, "work.bin")
            return
        self.samples = Rows(1 + 2 * problem.n, capacity)     # [t, q, v] per sample
        self.work = Rows(len(channels), capacity if channels else 0)

    @property
    def count(self):
        return self.samples.count

    @property
    def t(self):
        return self.samples.rows[:, 0]

    @property
    def q(self):
        return self.samples.rows[:, 1:1 + self.n]

    @property
    def v(self):
        return self.samples.rows[:, 1 + self.n:]

    def times_since(self, k):
        """The times of the samples from global index k on (recorded in this step)."""
        return self.samples.since(k)[:, 0]

    def _extra(self, ts, Y, Q, V) -> None:
        """The formulation's extras at the samples (ts, Q, V; rows Y of the state) being
        recorded (NaN where the state is not at hand)."""
        if Y is None:
            self.extra.extend(np.full((len(ts), self.extra.data.shape[1]), np.nan))
        else:
            self.extra.extend(self.extras(np.asarray(ts, float), np.atleast_2d(Y),
                                          np.atleast_2d(Q), np.atleast_2d(V)))

    def record(self, t, q, v, y=None) -> None:
        """One sample (t, q, v); `y`: the integrator's state there (for `extras`)."""
        check_finite(self.problem, t, q, v)
        if self.extras is not None:
            self._extra([t], y, q, v)
        s = self.samples
        s.room()
        row = s.data[s.held]
        row[0], row[1:1 + self.n], row[1 + self.n:] = t, q, v
        s.held += 1

    def record_many(self, ts, Q, V, Y=None) -> None:
        """`record` of the samples (ts[k], Q[k], V[k]) (states Y[k]) as one block (a sample
        that is not finite is found one by one: the ones before it are kept, and it
        raises)."""
        if not (np.isfinite(Q).all() and np.isfinite(V).all()):
            for k, (tk, q, v) in enumerate(zip(ts, Q, V)):
                self.record(tk, q, v, None if Y is None else Y[k])
            return
        if self.extras is not None:
            self._extra(ts, Y, Q, V)
        s, k, n = self.samples, len(ts), self.n
        s.room(k)
        block = s.data[s.held:s.held + k]
        block[:, 0], block[:, 1:1 + n], block[:, 1 + n:] = ts, Q, V
        s.held += k

    def flush(self) -> None:
        """Between steps: samples and work beyond a chunk go to disk (when streamed)."""
        self.samples.flush()
        self.work.flush()

    @property
    def failure(self) -> OSError | None:
        """Why writing the stream failed, if it did."""
        return getattr(self.samples, "failure", None) or getattr(self.work, "failure", None)

    def take(self):
        """(t, q, v) of the run, views into its one trimmed array (no copy)."""
        data = self.samples.take()
        return data[:, 0], data[:, 1:1 + self.n], data[:, 1 + self.n:]

    def due(self, t) -> bool:
        """Whether a sample falls exactly at the end of a step at t."""
        ts = self.ts
        return ts is None or (self.next < len(ts) and ts[self.next] == t)

    def record_due(self, t, q, v, y=None) -> None:
        """The sample at a step's end (`due`; `y` the state there)."""
        self.record(t, q, v, y)
        self.next += 1

    def within(self, t_lo, t_hi, through, values, states) -> None:
        """Record the output samples in (t_lo, t_hi), or (t_lo, t_hi] with `through`, from
        calls of the interpolant `values(times)` and of `states(times, Y) -> (Q, V)` (rows:
        the samples), `CHUNK` samples at a time: a step over many samples (a fine output
        grid, a loose tolerance) needs no more memory than one over a few."""
        ts, first = self.ts, self.next
        self.next = int(np.searchsorted(ts, t_hi, side="right" if through else "left"))
        inside = ts[first:self.next]
        inside = inside[inside > t_lo]
        for k in range(0, inside.size, CHUNK):
            self._chunk(inside[k:k + CHUNK], values, states)

    def _chunk(self, inside, values, states) -> None:
        Y = np.atleast_2d(values(inside).T)
        try:
            Q, V = states(inside, Y)
        except FAILURES:
            # One by one: the samples before the one that fails are kept (a run that
            # cannot go on returns them).
            for k in range(inside.size):
                q, v = states(inside[k:k + 1], Y[k:k + 1])
                self.record(inside[k], q[0], v[0], Y[k])
            return
        self.record_many(inside, Q, V, Y)


def split_rows(Y, n):
    """(Q, V) from rows [q, v, …] (a bridge's extension's numbers after them)."""
    Y = np.atleast_2d(Y)
    return Y[:, :n], Y[:, n:2 * n]
