"""docs/radio.md reimplemented independently, loop by loop, against the package's per-station throughput.

Only the shipped numbers come from the package (the tables' loader); every formula, the airtime over
independent sets, the contenders and Bianchi's collisions, the guard interval, the two passes and the
admission are written here again from the page (Bianchi's fixed point solved in the collision probability,
with another root finder).
"""

import itertools
import math
import re

import numpy as np
import pytest
from scipy.optimize import brentq

from uav_swarm.world.comms import Association, RadioConfig, evaluate_coverage
from uav_swarm.world.wifi.config import Ieee80211Config
from uav_swarm.world.wifi.tables import load_wifi_tables

LIGHT_M_S = 299_792_458.0
AL_HOURANI = {  # docs/radio.md, section 1: a, b, eta_LoS, eta_NLoS
    "suburban": (4.88, 0.43, 0.1, 21.0),
    "urban": (9.61, 0.16, 1.0, 20.0),
    "dense urban": (12.08, 0.11, 1.6, 23.0),
    "high-rise urban": (27.23, 0.08, 2.3, 34.0),
}
DATA_TONES = {20: 234, 40: 468, 80: 980}


def fspl_db(distance_m, frequency_hz):
    distance_m = max(distance_m, 1.0)
    constant_db = 20 * math.log10(frequency_hz) + 20 * math.log10(4 * math.pi / LIGHT_M_S)
    return 20 * math.log10(distance_m) + constant_db


def to_mw(dbm):
    return 10 ** (dbm / 10)


class Reference:
    """One world of the model, as the page states it."""

    def __init__(self, users, uavs, heights, channels, wifi, tables, min_rate, limit):
        self.users, self.uavs, self.heights, self.channels = users, uavs, heights, channels
        self.tables, self.min_rate, self.limit = tables, min_rate, limit
        self.wifi = wifi
        self.efficiency = wifi.mac_efficiency if wifi.mac_efficiency is not None else tables["efficiency"]
        k_all, n_all = range(len(uavs)), range(len(users))
        f = wifi.frequency_ghz * 1e9
        a, b, eta_los, eta_nlos = AL_HOURANI[wifi.environment]
        self.p_user = [[0.0] * len(uavs) for _ in n_all]
        for n in n_all:
            for k in k_all:
                r = math.hypot(uavs[k][0] - users[n][0], uavs[k][1] - users[n][1])
                h = heights[k]
                theta = math.degrees(math.atan2(h, r))
                p_los = 1 / (1 + a * math.exp(-b * (theta - a)))
                loss = fspl_db(math.hypot(r, h), f) + p_los * eta_los + (1 - p_los) * eta_nlos
                gains = wifi.tx_power_dbm + wifi.ap_antenna_gain_dbi + wifi.station_antenna_gain_dbi
                self.p_user[n][k] = gains - loss
        self.noise_dbm = -174 + 10 * math.log10(wifi.channel_width_mhz * 1e6) + wifi.noise_figure_db
        cca = wifi.cca_threshold_20mhz_dbm + 3 * math.log2(wifi.channel_width_mhz / 20)
        self.hear = [[False] * len(uavs) for _ in k_all]
        for i in k_all:
            for j in k_all:
                d = math.dist((*uavs[i], heights[i]), (*uavs[j], heights[j]))
                p_ap = wifi.tx_power_dbm + 2 * wifi.ap_antenna_gain_dbi - fspl_db(d, f)
                self.hear[i][j] = i != j and channels[i] == channels[j] and p_ap >= cca
        scale = DATA_TONES[wifi.channel_width_mhz] / DATA_TONES[20] * wifi.spatial_streams
        scale *= 13.6 / (12.8 + wifi.guard_interval_us)
        self.ladder = [rate * scale for rate in tables["rates"]]

    def independent_sets(self, active):
        k_all = range(len(self.uavs))
        for size in range(len(self.uavs) + 1):
            for group in itertools.combinations([k for k in k_all if active[k]], size):
                if not any(self.hear[i][j] for i in group for j in group):
                    yield set(group), self.tables["rho"] ** size

    def airtime(self, active):
        total, share = 0.0, [0.0] * len(self.uavs)
        for group, weight in self.independent_sets(active):
            total += weight
            for k in group:
                share[k] += weight
        return [s / total for s in share]

    def success(self, n):
        """Bianchi's share of the airtime that carries data, n contenders."""
        w, m, r = self.tables["cw_min"] + 1, self.tables["stages"], self.tables["ratio"]
        if n <= 1 + 1e-12 or r == 0:
            return 1.0

        def tau(p):
            return 2 / (1 + w + p * w * sum((2 * p) ** i for i in range(m)))

        p = brentq(lambda p: p - (1 - (1 - tau(p)) ** (n - 1)), 0.0, 1.0, xtol=1e-15)
        t = tau(p)
        ps = n * t * (1 - t) ** (n - 1) / (1 - (1 - t) ** n)
        return ps / (ps + (1 - ps) * r)

    def useful_airtime(self, active):
        """Each AP's airtime times its collision-free share (0 for an inactive AP)."""
        sets = list(self.independent_sets(active))
        airtime = self.airtime(active)
        useful = [0.0] * len(self.uavs)
        for k in range(len(self.uavs)):
            if not active[k]:
                continue
            neighbours = [j for j in range(len(self.uavs)) if active[j] and self.hear[k][j]]
            closed_k = {k, *neighbours}
            quiet_k = sum(weight for group, weight in sets if not group & closed_k)
            n = 1.0
            for j in neighbours:
                closed_j = {j} | {i for i in range(len(self.uavs)) if active[i] and self.hear[j][i]}
                n += sum(weight for group, weight in sets if not group & (closed_k | closed_j)) / quiet_k
            useful[k] = airtime[k] * self.success(n)
        return useful

    def sinr_db(self, n, k, active, airtime):
        interference = 0.0
        alpha = self.tables["alpha"]
        for j in range(len(self.uavs)):
            if j != k and active[j] and self.channels[j] == self.channels[k] and not self.hear[k][j]:
                interference += ((1 - alpha) + alpha * airtime[j]) * to_mw(self.p_user[n][j])
        return 10 * math.log10(to_mw(self.p_user[n][k]) / (to_mw(self.noise_dbm) + interference))

    def mcs(self, sinr_db):
        best = -1
        for m, threshold in enumerate(self.tables["sinr"]):
            if sinr_db >= threshold:
                best = m
        return best

    def rate(self, sinr_db):
        m = self.mcs(sinr_db)
        return 0.0 if m < 0 else self.ladder[m]

    def admits(self, k, stations, rate_k, new_rate, airtime):
        if self.limit is not None and len(stations) >= self.limit:
            return False
        return self.rate_holds(k, stations, rate_k, new_rate, airtime)

    def rate_holds(self, k, stations, rate_k, new_rate, airtime):
        if not self.wifi.rate_admission:
            return True
        rates = [rate_k[s] for s in stations] + [new_rate]
        if self.wifi.fairness == "airtime":
            return airtime[k] * self.efficiency * min(rates) / len(rates) >= self.min_rate
        return airtime[k] * self.efficiency / sum(1 / r for r in rates) >= self.min_rate

    def run(self, previous):
        n_all, k_all = range(len(self.users)), range(len(self.uavs))
        mcs0 = self.tables["sinr"][0]
        snr_ok = [[self.p_user[n][k] - self.noise_dbm >= mcs0 for k in k_all] for n in n_all]
        active = [any(snr_ok[n][k] for n in n_all) for k in k_all]
        airtime = self.airtime(active)
        useful = self.useful_airtime(active)
        rate = [[self.rate(self.sinr_db(n, k, active, airtime)) for k in k_all] for n in n_all]
        in_range = [[rate[n][k] > 0 for k in k_all] for n in n_all]
        association = [-1] * len(self.users)
        stations = {k: [] for k in k_all}
        strongest = [max([self.p_user[n][k] for k in k_all if in_range[n][k]], default=-math.inf)
                     for n in n_all]
        for n in sorted(n_all, key=lambda n: (-strongest[n], n)):  # incumbents: in range, their rate held
            k = previous[n]
            held = {s: rate[s][k] for s in stations[k]} if k >= 0 else {}
            if k >= 0 and in_range[n][k] and self.rate_holds(k, stations[k], held, rate[n][k], useful):
                association[n] = k
                stations[k].append(n)
        for n in sorted(n_all, key=lambda n: (-strongest[n], n)):
            if association[n] >= 0:
                continue
            for k in sorted(k_all, key=lambda k: (-self.p_user[n][k], k)):
                rates_k = {s: rate[s][k] for s in stations[k]}
                if in_range[n][k] and self.admits(k, stations[k], rates_k, rate[n][k], useful):
                    association[n] = k
                    stations[k].append(n)
                    break
        served = [len(stations[k]) > 0 for k in k_all]
        airtime = self.airtime(served)
        useful = self.useful_airtime(served)
        own_rate = [0.0] * len(self.users)
        for n in n_all:
            if association[n] >= 0:
                own_rate[n] = self.rate(self.sinr_db(n, association[n], served, airtime))
        throughput = [0.0] * len(self.users)
        for k in k_all:
            members = [n for n in stations[k] if own_rate[n] > 0]
            for n in members:
                if self.wifi.fairness == "airtime":
                    throughput[n] = useful[k] * self.efficiency * own_rate[n] / len(members)
                else:
                    throughput[n] = useful[k] * self.efficiency / sum(1 / own_rate[m] for m in members)
        return association, throughput


def tables_as_plain_numbers(path=None):
    tables = load_wifi_tables(path)
    return {"rates": [float(r) for r in tables.rate_20mhz_1ss_mbps],
            "sinr": [float(s) for s in tables.min_sinr_db],
            "efficiency": tables.mac_efficiency, "rho": tables.access_intensity,
            "alpha": tables.interference_airtime_weighting, "cw_min": tables.cw_min,
            "stages": tables.backoff_stages, "ratio": tables.collision_time_ratio}


def random_scene(seed, tmp_path):
    rng = np.random.default_rng(seed)
    n_uavs, n_users = int(rng.integers(1, 7)), int(rng.integers(0, 40))
    side = float(rng.choice([60.0, 200.0, 600.0]))
    width = int(rng.choice([20, 40]))
    channels = (36, 40, 44) if width == 20 else (38, 46, 151)
    tables_file = ""
    if rng.random() < 0.3:  # hidden APs for their airtime share, other access intensity and collisions
        tables_file = str(tmp_path / f"tables-{seed}.toml")
        text = open(load_wifi_tables().source, encoding="utf-8").read()
        for key, value in (("interference_airtime_weighting", f"{rng.uniform(0.2, 1.0):.3f}"),
                           ("access_intensity", f"{rng.uniform(5, 200):.2f}"),
                           ("cw_min", str(rng.choice([7, 15, 31]))),
                           ("backoff_stages", str(rng.integers(0, 7))),
                           ("collision_time_ratio", f"{rng.choice([0.0, rng.uniform(0.5, 3.0)]):.3f}")):
            text, n = re.subn(rf"^{key} = .*$", f"{key} = {value}", text, count=1, flags=re.MULTILINE)
            assert n == 1, key
        with open(tables_file, "w", encoding="utf-8") as out:
            out.write(text)
    wifi = Ieee80211Config(
        channel_width_mhz=width, channels=channels, environment=str(rng.choice(list(AL_HOURANI))),
        cca_threshold_20mhz_dbm=float(rng.choice([-82.0, -62.0])),
        fairness=str(rng.choice(["airtime", "throughput"])),
        rate_admission=bool(rng.random() < 0.8), tx_power_dbm=float(rng.uniform(10, 23)),
        spatial_streams=int(rng.integers(1, 3)), mac_efficiency=None if rng.random() < 0.7 else 0.55,
        guard_interval_us=float(rng.choice([0.8, 1.6, 3.2])),
        tables_file=tables_file)
    limit = int(rng.integers(1, 8)) if rng.random() < 0.2 else None
    minimum = float(rng.choice([0.0, 2.0, 5.0, 20.0]))
    radio = RadioConfig(propagation="802.11", ieee80211=wifi, min_user_rate_mbps=minimum, station_limit=limit)
    users = rng.uniform(0, side, (n_users, 2))
    uavs = rng.uniform(0, side, (n_uavs, 2))
    heights = rng.uniform(5, 50, n_uavs)
    plan = rng.choice(channels[: int(rng.integers(1, 4))], n_uavs)
    moved = users + rng.normal(0, side / 20, users.shape)
    return radio, users, moved, uavs, heights, plan, tables_as_plain_numbers(tables_file or None)


def assert_close(package, reference):
    np.testing.assert_allclose(package, reference, rtol=0.01, atol=1e-9)


@pytest.mark.parametrize("seed", range(120))
def test_the_package_equals_the_page(seed, tmp_path):
    radio, users, moved, uavs, heights, plan, tables = random_scene(seed, tmp_path)
    limit = radio.max_stations
    first = Reference(users.tolist(), uavs.tolist(), heights.tolist(), plan.tolist(), radio.ieee80211, tables,
                      radio.min_user_rate_mbps, limit)
    association, throughput = first.run([-1] * len(users))
    snapshot = evaluate_coverage(users, uavs, radio, heights, plan)
    assert snapshot.association.tolist() == association
    assert_close(snapshot.throughput_mbps, throughput)
    # A second instant of a sequence: the users moved, the incumbents are kept while in range.
    link = Association(radio)
    link.update(users, uavs, altitudes_m=heights, channels=plan)
    second = Reference(moved.tolist(), uavs.tolist(), heights.tolist(), plan.tolist(), radio.ieee80211,
                       tables, radio.min_user_rate_mbps, limit)
    association_2, throughput_2 = second.run(association)
    sequence = link.update(moved, uavs, altitudes_m=heights, channels=plan)
    assert sequence.association.tolist() == association_2
    assert_close(sequence.throughput_mbps, throughput_2)
