"""The true world: depth(x, y), current(x, y, t) and wind(x, y, t) as numpy-vectorised fields."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from forcemap.host.vessel import tides
from forcemap.host.vessel.scenario import Scenario

from .effects import Effect

ArrayLike = float | np.ndarray


def smoothstep(u: ArrayLike) -> ArrayLike:
    """0 before 0, 1 after 1, a smooth S between."""
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def rating_stage(q: ArrayLike, scale_m: float, b: float = 1.6) -> ArrayLike:
    """Stage (m) above the stage at relative discharge 1 on a rating curve Q = C (h - e)^b (USGS): with
    h - e = scale_m at Q0, the stage at Q is scale_m ((Q / Q0)^(1 / b) - 1)."""
    return scale_m * (np.power(np.asarray(q, dtype=float), 1.0 / b) - 1.0)


@dataclass
class Point:
    """Every true field at one place and time (SI, vectors as velocities of the medium)."""

    depth: float
    current_east: float
    current_north: float
    wind_east: float
    wind_north: float
    water_temp: float


class World:
    """Depth, current, wind and water temperature for one scenario with its world effects switched on.

    Times ``t`` are seconds since the start of the run.
    """

    def __init__(
        self, scenario: Scenario, effects: list[Effect], duration_s: float, seed: int = 0
    ) -> None:
        self.sc = scenario
        self.duration_s = max(float(duration_s), 1.0)
        self.on = {e.name: e.params for e in effects if e.spec.kind == "world"}
        self.t0 = float(scenario.t0)  # UNIX seconds of t = 0: the tidal stream's astronomy
        self._tide_tables: dict[int, np.ndarray] = {}
        self.reference_stream = None  # a subordinate station's stream (sim_devices/reference_stream.py)
        rng = np.random.default_rng([seed, 101])
        x0, x1, y0, y1 = scenario.extent
        self.half_span_x = 0.5 * (x1 - x0)
        self.is_river = scenario.kind == "river"
        if "reference_stream" in self.on:
            from .reference_stream import ReferenceStream

            self.reference_stream = ReferenceStream(
                self.on["reference_stream"], self.t0, 0.5 * (x0 + x1), self.half_span_x
            )
        self._init_geometry()
        self._init_wind(rng)

    # ---- geometry and depth -------------------------------------------------------------
    def _init_geometry(self) -> None:
        t = self.sc.tables
        if self.is_river:
            ch, d, c = t["channel"], t["depth"], t["current"]
            self.k = 2.0 * math.pi / float(ch["meander_wavelength"])
            self.amp = float(ch["meander_amplitude"])
            self.phase = math.radians(float(ch.get("meander_phase_deg", 0.0)))
            self.half_width = float(ch["half_width"])
            self.th_amp = float(ch["thalweg_amplitude"])
            self.th_phase = math.radians(float(ch.get("thalweg_phase_deg", 0.0)))
            self.d_bank, self.d_th = float(d["bank"]), float(d["thalweg"])
            self.d_width = float(d["width"])
            self.d_min, self.d_max = float(d["min"]), float(d["max"])
            bars = np.array(d.get("bars", []), dtype=float).reshape(-1, 4)
            self.bars = bars
            self.u_bank, self.u_th = float(c["bank"]), float(c["thalweg"])
        else:
            b = t["basin"]
            self.deep = (float(b["deep_x"]), float(b["deep_y"]))
            self.d_centre, self.d_edge = float(b["depth_centre"]), float(b["depth_edge"])
            self.radius = float(b["radius"])
            self.drift = float(b["drift"])
            self.d_min, self.d_max = 0.5, self.d_centre
            self.bars = np.zeros((0, 4))
        self.manning = float(self.on.get("depth_current", {}).get("exponent", 2.0 / 3.0))

    def _bank_coords(self, x: ArrayLike, y: ArrayLike) -> tuple[ArrayLike, ArrayLike]:
        """Cross-channel offset n from the centreline, and the centreline's direction (math rad)."""
        arg = self.k * x + self.phase
        n = y - self.amp * np.sin(arg)
        theta = np.arctan(self.amp * self.k * np.cos(arg))
        return n, theta

    def _smooth_depth(self, x: ArrayLike, y: ArrayLike) -> ArrayLike:
        if self.is_river:
            n, _ = self._bank_coords(x, y)
            nt = self.th_amp * np.sin(self.k * x + self.th_phase)
            return self.d_bank + (self.d_th - self.d_bank) * np.exp(
                -(((n - nt) / self.d_width) ** 2)
            )
        r2 = (x - self.deep[0]) ** 2 + (y - self.deep[1]) ** 2
        d = self.d_centre - (self.d_centre - self.d_edge) * r2 / self.radius**2
        return max(d, 0.5) if isinstance(d, float) else np.clip(d, 0.5, None)

    def depth(self, x: ArrayLike, y: ArrayLike) -> ArrayLike:
        """Water depth below the surface at rest (m): the bed; a sounding adds `water_level(t)`."""
        return self._depth(x, y, self._smooth_depth(x, y))

    def _depth(self, x: ArrayLike, y: ArrayLike, ds: ArrayLike) -> ArrayLike:
        d = ds
        for xb, yb, rb, hb in self.bars:
            d = d - hb * np.exp(-((x - xb) ** 2 + (y - yb) ** 2) / (rb * rb))
        if isinstance(d, float):  # one place (the boat loop's every step): np.clip's own arithmetic
            return min(max(d, self.d_min), self.d_max)
        return np.clip(d, self.d_min, self.d_max)

    # ---- the water surface --------------------------------------------------------------
    def water_level(self, t: ArrayLike) -> ArrayLike:
        """The water surface's height (m) above its level at rest (no tide, the starting discharge): a tide,
        and a stage following the discharge through a rating curve. Soundings are deeper by it."""
        t = np.asarray(t, dtype=float)
        level = np.zeros_like(t)
        tide = self.on.get("tide")
        if tide is not None:
            arg = 2 * math.pi * (t - 0.5 * self.duration_s) / tide["period_s"]
            level = level + tide["amplitude_m"] * np.sin(arg + math.radians(tide["phase_deg"]))
        stage = self.on.get("stage")
        if stage is not None:
            level = level + rating_stage(self.discharge_factor(t), stage["scale_m"], stage["b"])
        return level if level.ndim else float(level)

    # ---- current ------------------------------------------------------------------------
    def discharge_factor(self, t: ArrayLike) -> ArrayLike:
        """Discharge relative to the start: 1 unless dam_release is on."""
        p = self.on.get("dam_release")
        if p is None:
            return np.ones_like(np.asarray(t, dtype=float)) if np.ndim(t) else 1.0
        ta, tb = p["start_frac"] * self.duration_s, p["end_frac"] * self.duration_s
        return 1.0 + p["increase"] * smoothstep((np.asarray(t, dtype=float) - ta) / (tb - ta))

    def current(self, x: ArrayLike, y: ArrayLike, t: ArrayLike) -> tuple[ArrayLike, ArrayLike]:
        """Surface current (east, north) in m/s: the water's velocity."""
        ds = self._smooth_depth(x, y)
        return self._current(x, y, t, ds, self._depth(x, y, ds))

    def tidal_stream(self, t: ArrayLike) -> ArrayLike:
        """The tidal stream along the channel (m/s, with the flow positive) at run times `t`: 0 without it.
        One time (the boat loop's) is read from an hour's table every 10 s (the stream's error there is
        below 1e-5 of its amplitude)."""
        p = self.on.get("tidal_stream")
        if p is None:
            return 0.0 * np.asarray(t, dtype=float)
        if not np.ndim(t):
            hour = math.floor(float(t) / 3600.0)
            table = self._tide_tables.get(hour)
            if table is None:
                table = self._tide_tables[hour] = self._tidal(
                    3600.0 * hour + np.arange(0, 3611, 10.0)
                )
            return float(np.interp(float(t), 3600.0 * hour + np.arange(0, 3611, 10.0), table))
        return self._tidal(t)

    def _tidal(self, t: ArrayLike) -> ArrayLike:
        p = self.on["tidal_stream"]
        names, amps, phases = ["M2"], [p["amplitude_m_s"]], [p["phase_deg"]]
        if p["s2_m_s"]:
            names, amps, phases = names + ["S2"], amps + [p["s2_m_s"]], phases + [p["s2_phase_deg"]]
        tt = np.asarray(t, dtype=float).ravel()
        F, U, V = tides.fuv(self.t0 + tt, names, self.sc.lat0)
        arg = 2 * np.pi * (V + U) - np.radians(phases)
        out = (F * np.asarray(amps) * np.cos(arg)).sum(axis=1)
        return out.reshape(np.shape(t)) if np.ndim(t) else float(out[0])

    def oscillation(self, t: ArrayLike) -> ArrayLike:
        """The current added along the flow by a tidal stream and a seiche at run times `t` (m/s)."""
        out = self.tidal_stream(t) if "tidal_stream" in self.on else 0.0 * np.asarray(t, dtype=float)
        p = self.on.get("seiche")
        if p is not None:
            arg = 2 * math.pi * np.asarray(t, dtype=float) / p["period_s"] + math.radians(p["phase_deg"])
            out = out + p["amplitude_m_s"] * np.sin(arg)
        return out

    def _current(self, x, y, t, ds, d):  # type: ignore[no-untyped-def]
        q = self.discharge_factor(t)
        tidal = self.on.get("tidal_stream") or self.on.get("reference_stream")
        tide = self.oscillation(t)
        if self.reference_stream is not None:
            tide = tide + self.reference_stream(x, t)
        if tidal is not None:
            q = q * tidal["river"]
        if self.is_river:
            if "depth_current" in self.on:
                # Manning: with one slope and one bed roughness, the speed goes as depth^(2/3) everywhere
                speed = self.u_th * np.power(np.asarray(d) / self.d_th, self.manning) * q
            else:
                frac = (ds - self.d_bank) / (self.d_th - self.d_bank)
                speed = (self.u_bank + (self.u_th - self.u_bank) * frac) * q
            _, theta = self._bank_coords(x, y)
            speed = speed + tide
            return speed * np.cos(theta), speed * np.sin(theta)
        a = math.radians(self.sc.flow_dir_deg)
        speed = self.drift * q * (1.0 + 0.1 * np.sin(0.03 * x) * np.cos(0.03 * y))
        if "depth_current" in self.on:
            speed = speed * (d / ds) ** self.manning
        speed = speed + tide
        return speed * math.sin(a), speed * math.cos(a)

    # ---- wind ---------------------------------------------------------------------------
    def _init_wind(self, rng: np.random.Generator) -> None:
        w = self.sc.tables["wind"]
        self.w_speed = float(w["speed"])
        self.w_from = float(w["from_deg"])
        self.w_grad = float(w.get("gradient", 0.0))
        self.shelter_bank = str(w.get("shelter_bank", "none"))
        self.shelter_static = float(w.get("shelter_static", 0.0))
        self.shelter_len = float(w.get("shelter_length", 50.0))
        # with bank_shelter the direction also wanders over seconds (random phases, drawn before the gusts')
        nv = 12
        vp = np.exp(rng.uniform(math.log(10.0), math.log(60.0), nv))
        self.v_omega, self.v_phase = 2 * math.pi / vp, rng.uniform(0, 2 * math.pi, nv)
        g = self.on.get("gusts")
        self.gust_events = np.zeros((0, 3))
        if g is None:
            return
        nk = 24
        periods = np.exp(rng.uniform(math.log(8.0), math.log(60.0), nk))
        self.g_omega = 2 * math.pi / periods
        self.g_phase = rng.uniform(0, 2 * math.pi, nk)
        amp = periods**0.5
        self.g_amp = amp * g["fast_std"] / math.sqrt(0.5 * float(np.sum(amp * amp)))
        self.g_slow_phase = float(rng.uniform(0, 2 * math.pi))
        # strong gust events so the gust factor reaches peak_factor in every run, one per ~6 minutes
        n_ev = max(1, int(self.duration_s // 360))
        times = (np.arange(n_ev) + rng.uniform(0.25, 0.75, n_ev)) * self.duration_s / n_ev
        ev = []
        for te in times:
            g0 = float(self._gust_factor_at(np.array([te]))[0])
            need = max(0.0, g["peak_factor"] * 1.04 - g0)
            ev.append((te, need, rng.uniform(3.0, 5.0)))
        self.gust_events = np.array(ev)

    def _gust_factor_at(self, tau: np.ndarray) -> np.ndarray:
        g = self.on["gusts"]
        slow = g["slow_amplitude"] * np.sin(
            2 * math.pi * tau / g["slow_period_s"] + self.g_slow_phase
        )
        fast = np.sin(np.multiply.outer(tau, self.g_omega) + self.g_phase) @ self.g_amp
        out = 1.0 + slow + fast
        for te, a, width in self.gust_events:
            out = out + a * np.exp(-(((tau - te) / width) ** 2))
        return np.maximum(out, 0.2)

    def wind_from_deg(self, t: ArrayLike) -> ArrayLike:
        """Direction the wind comes from (compass deg) at time t; veers and backs only with bank_shelter."""
        p = self.on.get("bank_shelter")
        if p is None:
            return self.w_from + 0.0 * np.asarray(t, dtype=float)
        t = np.asarray(t, dtype=float)
        u = 0.5 - 0.5 * np.cos(2 * math.pi * t / p["swing_period_s"])
        wander = np.sin(np.multiply.outer(t, self.v_omega) + self.v_phase).sum(axis=-1)
        wander = wander * (p["wander_deg"] / math.sqrt(0.5 * len(self.v_omega)))
        return p["veer_from_deg"] + (p["veer_to_deg"] - p["veer_from_deg"]) * u + wander

    def _bank_distance(self, x: ArrayLike, y: ArrayLike) -> tuple[ArrayLike, float]:
        """Distance to the sheltering bank (m) and the direction (compass deg) the bank lies in."""
        if not self.is_river or self.shelter_bank == "none":
            return np.full_like(np.asarray(x, dtype=float), 1e9), 0.0
        n, _ = self._bank_coords(x, y)
        if self.shelter_bank == "south":
            return np.maximum(n + self.half_width, 0.0), 180.0
        return np.maximum(self.half_width - n, 0.0), 0.0

    def wind(self, x: ArrayLike, y: ArrayLike, t: ArrayLike) -> tuple[ArrayLike, ArrayLike]:
        """True wind (east, north) in m/s: the air's velocity over ground."""
        x = np.asarray(x, dtype=float)
        y = np.asarray(y, dtype=float)
        t = np.asarray(t, dtype=float)
        frm = np.radians(self.wind_from_deg(t))
        speed = self.w_speed * (1.0 + self.w_grad * x / self.half_span_x)
        dist, bank_dir = self._bank_distance(x, y)
        p = self.on.get("bank_shelter")
        if p is None:
            speed = speed * (1.0 - self.shelter_static * np.exp(-dist / self.shelter_len))
        else:
            facing = np.maximum(np.cos(frm - math.radians(bank_dir)), 0.0)
            speed = speed * (1.0 - p["strength"] * facing * np.exp(-dist / p["length_m"]))
        if "gusts" in self.on:
            # gusts travel with the wind: the gust at a point arrives later further downwind
            along = -(x * np.sin(frm) + y * np.cos(frm))
            tau = np.asarray(t - along / self.w_speed, dtype=float)
            speed = speed * self._gust_factor_at(tau.reshape(-1)).reshape(tau.shape)
        return -speed * np.sin(frm), -speed * np.cos(frm)

    # ---- water temperature --------------------------------------------------------------
    def water_temp(self, x: ArrayLike, y: ArrayLike) -> ArrayLike:
        w = self.sc.tables.get("water", {})
        return float(w.get("temp", 25.0)) + float(w.get("temp_gradient", 0.0)) * (
            np.asarray(x, dtype=float) / self.half_span_x
        )

    # ---- everything at once (the hot path of the boat loop) -----------------------------
    def at(self, x: float, y: float, t: float) -> Point:
        ds = self._smooth_depth(x, y)
        d = self._depth(x, y, ds)
        ce, cn = self._current(x, y, t, ds, d)
        we, wn = self.wind(x, y, t)
        level = self.water_level(t) if ("tide" in self.on or "stage" in self.on) else 0.0
        return Point(
            float(d + level),
            float(ce),
            float(cn),
            float(we),
            float(wn),
            float(self.water_temp(x, y)),
        )

    def grid(self, nx: int = 121, ny: int = 41) -> tuple[np.ndarray, np.ndarray]:
        x0, x1, y0, y1 = self.sc.extent
        return np.linspace(x0, x1, nx), np.linspace(y0, y1, ny)
