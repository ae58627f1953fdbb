"""A Modbus VFD stand-in for the logger tests (run as a script): serves a register block whose values
follow known signals of the wall clock, and appends every served response to a record file.

    python vfd_server.py PORT RECORD_FILE [rtu]

Registers (holding, as a Delta MS300 map reads them): 0x2103 output frequency (0.01 Hz), 0x2104 output
current (0.01 A), 0x210C motor speed (rpm), 0x210F output power (W); every 4th second of the clock
the current register answers with an exception (device busy) for 0.1 s.
"""

from __future__ import annotations

import math
import sys
import time

from pymodbus import FramerType
from pymodbus.constants import ExcCodes
from pymodbus.server import StartTcpServer
from pymodbus.simulator import SimData, SimDevice
from pymodbus.simulator.simutils import DataType

BASE = 0x2100


def values(t: float) -> dict[int, int]:
    """Raw register values at wall time t (s): the known signals."""
    return {0x2103: int(round(20000 + 10000 * math.sin(2 * math.pi * 0.3 * t))),
            0x2104: int(round(1500 + 700 * math.sin(2 * math.pi * 1.1 * t + 1.0))),
            0x210C: int(round(12000 + 6000 * math.sin(2 * math.pi * 0.3 * t))),
            0x210F: int(round(900 + 400 * math.sin(2 * math.pi * 0.7 * t + 2.0)))}


def main() -> None:
    port, record = int(sys.argv[1]), open(sys.argv[2], "a", buffering=1)
    framer = FramerType.RTU if len(sys.argv) > 3 and sys.argv[3] == "rtu" else FramerType.SOCKET

    async def action(function_code, start_address, address, count, registers, set_values):
        now = time.time()
        if (now % 4.0) < 0.1 and address <= 0x2104 < address + count:
            record.write(f"{now:.6f} exception\n")
            return ExcCodes.DEVICE_BUSY
        vals = values(now)
        for a, v in vals.items():
            if address <= a < address + count:
                registers[a - start_address] = v
        served = " ".join(str(registers[a - start_address]) for a in range(address, address + count))
        record.write(f"{now:.6f} {served}\n")
        return None

    device = SimDevice(id=1, simdata=[SimData(BASE, count=32, values=0, datatype=DataType.REGISTERS)], action=action)
    StartTcpServer(device, address=("127.0.0.1", port), framer=framer)


if __name__ == "__main__":
    main()
