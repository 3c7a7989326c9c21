"""Run one calibration scene in ns-3 and write what each station received (run in its own process).

This file runs under the Python that has the PyPI ``ns3`` package (``pip install ns3``, the
``radio-calibration`` extra) and imports nothing of the project, so that an abort inside ns-3 only ends
this process. It reads a job (JSON, written by ``run_ns3.py``) and writes a result (JSON, atomically):

- the network: access points and stations at the job's 3-D positions; each access point on its own channel
  number and width (5 GHz band), its stations on the same channel with the access point's SSID (passive
  scanning, association before the measurement starts); 802.11ax, one spatial stream, the job's guard interval
  (``run_ns3.py`` sets 0.8 us unless told; ns-3's default is 3.2 us), every radio transmitting at
  ``tx_power_dbm``; ns-3's defaults otherwise (noise figure 7 dB, preamble detection and carrier sense at -82
  dBm, A-MPDUs up to 65,535 bytes, no RTS/CTS, EDCA best effort, the table-based error model);
- the path loss: ``MatrixPropagationLossModel`` with the job's dB matrix (every pair, symmetric), so that ns-3
  compares only its MAC and PHY with the project's model; constant-speed propagation delay;
- the rate: the job's remote station manager (``ns3::IdealWifiManager`` by default: the MCS whose table-based
  error rate is low enough at the SINR of the last frame received from the peer);
- the traffic: a saturated UDP downlink, 1,472-byte datagrams from each access point to each of its stations,
  ``offered_mbps_per_ap`` split equally over its stations (well above what an access point can carry). The
  access point's queueing is ns-3's as shipped: the traffic-control layer's default root queue discipline
  (FqCoDel, fair per flow) over the Wi-Fi MAC's first-come first-served queue, so that at saturation every
  station of an access point receives the same throughput whatever its rate (throughput fairness, the 802.11
  performance anomaly);
- the measurement: datagrams received by each station's UDP server between ``warmup_s`` and
  ``warmup_s + measure_s``, and for each station the data PPDUs sent to it by MCS (``PhyTxPsduBegin``).

Each seed (``RngSeedManager`` run number) is a fresh simulation in the same process; several jobs may be
given (one import of ns-3 for all), each result is written as soon as its job is done.

Usage: python ns3_scene.py JOB.json RESULT.json [JOB.json RESULT.json ...]
"""

from __future__ import annotations

import json
import os
import sys
import time

from ns import ns

PAYLOAD_BYTES = 1472
PORT = 9

ns.cppyy.cppdef(r"""
#include <map>
#include <sstream>
#include <string>
namespace calib {
// receiver MAC address -> MCS -> {data PPDUs, PSDU bytes}, counted while `counting` is set
std::map<std::string, std::map<int, std::pair<long, long>>> sent;
bool counting = false;
void PsduBegin(std::string context, ns3::WifiConstPsduMap psdus, ns3::WifiTxVector txVector, double powerW) {
  if (!counting) return;
  for (auto& entry : psdus) {
    auto psdu = entry.second;
    if (!psdu->GetHeader(0).IsQosData()) continue;
    std::ostringstream address;
    address << psdu->GetAddr1();
    auto& cell = sent[address.str()][txVector.GetMode(entry.first).GetMcsValue()];
    cell.first += 1;
    cell.second += psdu->GetSize();
  }
}
void Connect() {
  ns3::Config::Connect("/NodeList/*/DeviceList/*/$ns3::WifiNetDevice/Phy/PhyTxPsduBegin",
                       ns3::MakeCallback(&PsduBegin));
}
void Reset() { sent.clear(); counting = false; }
}
""")


def _node_container(nodes: list) -> object:
    container = ns.NodeContainer()
    for node in nodes:
        container.Add(node)
    return container


def run_seed(job: dict, seed: int) -> dict:
    """Simulate the job once with ns-3's run number ``seed``; per-station throughput and MCS counts."""
    ns.RngSeedManager.SetSeed(1)
    ns.RngSeedManager.SetRun(seed)
    ns.cppyy.gbl.calib.Reset()
    positions = job["positions_m"]
    ap_of = job["serving_ap"]  # per node: -1 for an access point, else the node of the station's access point
    n_nodes = len(positions)
    nodes = ns.NodeContainer()
    nodes.Create(n_nodes)

    allocator = ns.CreateObject[ns.ListPositionAllocator]()
    for x_m, y_m, z_m in positions:
        allocator.Add(ns.Vector(x_m, y_m, z_m))
    mobility = ns.MobilityHelper()
    mobility.SetMobilityModel("ns3::ConstantPositionMobilityModel")
    mobility.SetPositionAllocator(allocator)
    mobility.Install(nodes)
    models = [nodes.Get(i).GetObject[ns.MobilityModel]() for i in range(n_nodes)]

    loss = ns.CreateObject[ns.MatrixPropagationLossModel]()
    loss.SetDefaultLoss(500.0)
    loss_db = job["loss_db"]
    for i in range(n_nodes):
        for j in range(i + 1, n_nodes):
            loss.SetLoss(models[i], models[j], float(loss_db[i][j]), True)
    channel = ns.CreateObject[ns.YansWifiChannel]()
    channel.SetPropagationLossModel(loss)
    channel.SetPropagationDelayModel(ns.CreateObject[ns.ConstantSpeedPropagationDelayModel]())

    ap_nodes = [i for i in range(n_nodes) if ap_of[i] < 0]
    devices = [None] * n_nodes
    for k, ap_node in enumerate(ap_nodes):
        phy = ns.YansWifiPhyHelper()
        phy.SetChannel(channel)
        phy.Set("ChannelSettings", ns.StringValue(
            f"{{{job['channels'][k]}, {job['width_mhz'][k]}, BAND_5GHZ, 0}}"))
        phy.Set("TxPowerStart", ns.DoubleValue(job["tx_power_dbm"]))
        phy.Set("TxPowerEnd", ns.DoubleValue(job["tx_power_dbm"]))
        wifi = ns.WifiHelper()
        wifi.SetStandard(ns.WIFI_STANDARD_80211ax)
        wifi.SetRemoteStationManager(job["rate_manager"])
        wifi.ConfigHeOptions("GuardInterval", ns.TimeValue(ns.NanoSeconds(job["guard_interval_ns"])))
        mac = ns.WifiMacHelper()
        ssid = ns.Ssid(f"uav-{k}")
        mac.SetType("ns3::ApWifiMac", "Ssid", ns.SsidValue(ssid))
        devices[ap_node] = wifi.Install(phy, mac, nodes.Get(ap_node)).Get(0)
        stations = [i for i in range(n_nodes) if ap_of[i] == ap_node]
        if stations:
            mac.SetType("ns3::StaWifiMac", "Ssid", ns.SsidValue(ssid),
                        "ActiveProbing", ns.BooleanValue(False))
            installed = wifi.Install(phy, mac, _node_container([nodes.Get(i) for i in stations]))
            for n, i in enumerate(stations):
                devices[i] = installed.Get(n)

    all_devices = ns.NetDeviceContainer()
    for device in devices:
        all_devices.Add(device)
    ns.InternetStackHelper().Install(nodes)
    addresses = ns.Ipv4AddressHelper()
    addresses.SetBase(ns.Ipv4Address("10.1.0.0"), ns.Ipv4Mask("255.255.0.0"))
    interfaces = addresses.Assign(all_devices)
    ns.NeighborCacheHelper().PopulateNeighborCache()

    station_nodes = [i for i in range(n_nodes) if ap_of[i] >= 0]
    servers = {}
    start_rng = ns.CreateObject[ns.UniformRandomVariable]()
    for i in station_nodes:
        per_station_mbps = job["offered_mbps_per_ap"] / sum(1 for a in ap_of if a == ap_of[i])
        server = ns.UdpServerHelper(PORT).Install(nodes.Get(i))
        server.Start(ns.Seconds(0.0))
        servers[i] = server.Get(0)
        client = ns.UdpClientHelper(interfaces.GetAddress(i).ConvertTo(), PORT)
        client.SetAttribute("MaxPackets", ns.UintegerValue(0))
        client.SetAttribute("PacketSize", ns.UintegerValue(PAYLOAD_BYTES))
        interval_s = PAYLOAD_BYTES * 8 / (per_station_mbps * 1e6)
        client.SetAttribute("Interval", ns.TimeValue(ns.Seconds(interval_s)))
        app = client.Install(nodes.Get(ap_of[i]))
        app.Start(ns.Seconds(0.05 + 0.05 * start_rng.GetValue()))

    ns.cppyy.gbl.calib.Connect()
    ns.Simulator.Stop(ns.Seconds(job["warmup_s"]))
    ns.Simulator.Run()
    before = {i: int(servers[i].GetReceived()) for i in station_nodes}
    ns.cppyy.gbl.calib.counting = True
    ns.Simulator.Stop(ns.Seconds(job["measure_s"]))
    ns.Simulator.Run()
    after = {i: int(servers[i].GetReceived()) for i in station_nodes}
    ns.cppyy.gbl.calib.counting = False

    sent = ns.cppyy.gbl.calib.sent
    stations = []
    for i in station_nodes:
        mac_address = str(ns.Mac48Address.ConvertFrom(devices[i].GetAddress()))
        per_mcs = {}
        if sent.count(mac_address):
            for item in sent[mac_address]:
                per_mcs[int(item.first)] = [int(item.second.first), int(item.second.second)]
        stations.append({
            "node": i,
            "throughput_mbps": (after[i] - before[i]) * PAYLOAD_BYTES * 8 / job["measure_s"] / 1e6,
            "data_ppdus_by_mcs": per_mcs,
        })
    ns.Simulator.Destroy()
    return {"seed": seed, "stations": stations}


def main(argv: list[str]) -> int:
    if not argv or len(argv) % 2:
        print("usage: ns3_scene.py JOB.json RESULT.json [JOB.json RESULT.json ...]", file=sys.stderr)
        return 2
    for job_path, result_path in zip(argv[::2], argv[1::2], strict=True):
        with open(job_path, encoding="utf-8") as handle:
            job = json.load(handle)
        runs = []
        for seed in job["seeds"]:
            started = time.perf_counter()
            run = run_seed(job, seed)
            run["wall_s"] = round(time.perf_counter() - started, 2)
            runs.append(run)
            print(f"{job['name']} seed {seed}: {sum(s['throughput_mbps'] for s in run['stations']):.1f} Mbps "
                  f"in {run['wall_s']} s", flush=True)
        result = {"name": job["name"], "job": job, "runs": runs, "ns3_version": "3.44 (PyPI ns3)"}
        tmp = result_path + ".tmp"
        with open(tmp, "w", encoding="utf-8") as handle:
            json.dump(result, handle)
        os.replace(tmp, result_path)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
