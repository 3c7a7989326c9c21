"""The SNR at which ns-3's ideal rate manager starts using each 802.11ax MCS (run under the ns3 Python).

``IdealWifiManager`` uses the fastest MCS whose threshold is below the SNR last observed from the peer; the
threshold of an MCS is the SNR at which the PHY's error model (``TableBasedErrorRateModel``, ns-3's default)
reaches the manager's bit error rate (``BerThreshold``, 1e-6), computed by ``ErrorRateModel::CalculateSnr``.
This prints them (dB) for HE single-user PPDUs, one spatial stream, 0.8 us guard interval, at each channel
width, as JSON; ``calibrate.py`` compares them with the stations' MCS in the scenes.

Usage: python ns3_thresholds.py OUT.json
"""

from __future__ import annotations

import json
import math
import os
import sys

from ns import ns

BER = 1e-6


def thresholds_db(width_mhz: int) -> list[float]:
    """The twelve HE MCS thresholds (dB) at ``width_mhz``."""
    model = ns.CreateObject[ns.TableBasedErrorRateModel]()
    out = []
    for mcs in range(12):
        vector = ns.WifiTxVector()
        vector.SetMode(ns.HePhy.GetHeMcs(mcs))
        vector.SetPreambleType(ns.WIFI_PREAMBLE_HE_SU)
        vector.SetChannelWidth(width_mhz)
        vector.SetNss(1)
        vector.SetGuardInterval(ns.NanoSeconds(800))
        out.append(round(10.0 * math.log10(model.CalculateSnr(vector, BER)), 2))
    return out


def main(argv: list[str]) -> int:
    (out,) = argv
    document = {"ber": BER, "error_model": "ns3::TableBasedErrorRateModel",
                "min_snr_db": {str(w): thresholds_db(w) for w in (20, 40, 80)}}
    tmp = out + ".tmp"
    with open(tmp, "w", encoding="utf-8") as handle:
        json.dump(document, handle, indent=1)
    os.replace(tmp, out)
    print(json.dumps(document))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
