"""A benchmark driver (bench-nav): the firmware's Navigator alone inside the real MicroPython
VM on simulated data, counting what every tick allocates.

On the board each float result is a 16-byte heap box, so the GC blocks a tick allocates are
its number of boxed float operations, the best proxy for its CPU time (docs/requirements.md, time
budget). The VM counts them exactly (gc.mem_alloc with the collector off); what it cannot show is
time: its floats are doubles and it runs on a PC. Blocks are net: a function with many locals gets
its call frame from the heap and frees it on return, which costs allocator time but no block.
"""

import json
import pathlib
import tempfile

import numpy as np

from host_emulator.runtimes.mpy_unix import vm

_SCRIPT = """
import array, gc, json
import navcfg, nav
cfg = navcfg.NavConfig({profile!r})
for i in range(3):
    cfg.lever_b_m[i] = {lever!r}[i]
if {slices} is not None:
    cfg.slices_per_tick = {slices}
if {coning} is not None:
    cfg.coning = {coning}
n = nav.Navigator(cfg)
with open({imu_path!r}, 'rb') as f:
    counts = array.array('h', f.read())
with open({fix_path!r}) as f:
    fixes = json.load(f)
N = len(counts) // 6
blocks = array.array('H', bytes(2 * N))
state = bytearray(N)
g = [0, 0, 0]
a = [0, 0, 0]
fi = 0
gc.collect()
gc.disable()
for k in range(N):
    while fi < len(fixes) and fixes[fi][0] <= k:
        x = fixes[fi]
        n.gnss(x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8], x[9])
        fi += 1
    b = 6 * k
    g[0] = counts[b]
    g[1] = counts[b + 1]
    g[2] = counts[b + 2]
    a[0] = counts[b + 3]
    a[1] = counts[b + 4]
    a[2] = counts[b + 5]
    m0 = gc.mem_alloc()
    n.imu_raw(g, a, False)
    m1 = gc.mem_alloc()
    d = (m1 - m0) // _BPB
    blocks[k] = d if d < 65535 else 65535
    state[k] = n.state
    if k & 31 == 0:
        gc.collect()
        gc.disable()
# the per-tick arrays as hex lines (a JSON list of 36k ints does not fit the VM's heap)
import binascii
for i in range(0, N, 2048):
    print('B', binascii.hexlify(blocks[i:i + 2048]).decode())
    print('S', binascii.hexlify(state[i:i + 2048]).decode())
print(json.dumps({{
    "p_n": list(n.ins.p_n), "v_n": list(n.ins.v_n), "q_bn": list(n.ins.q_bn),
    "updates": n.updates, "tick": n.tick,
}}))
"""


def run(imu, gnss, duration_s, profile="car", slices_per_tick=None, coning=None, timeout=900):
    """Feed `duration_s` of simulated data to the navigator in the VM; per-tick blocks etc.
    slices_per_tick and coning override the configuration's defaults when given."""
    dt = 0.005
    n = min(len(imu.gyro_counts) - 1, int(round(duration_s / dt)))
    counts = np.concatenate([imu.gyro_counts[:n], imu.accel_counts[:n]], axis=1)
    fixes = []
    from host_emulator.bench import navigator as nav_runner

    divmod_e7 = nav_runner.geo.split_e7  # the firmware's (degrees, fraction) longitude
    for f in gnss:
        k = int(np.ceil(f.t_avail_s / dt - 1e-9))
        if k >= n:
            break
        course = -1.0 if np.isnan(f.course_deg) else float(np.radians(f.course_deg))
        fixes.append(
            [
                k,
                int(f.lat_e7),
                *divmod_e7(int(f.lon_e7)),
                float(f.h_m),
                int(f.quality),
                float(f.hdop),
                float(f.speed_m_s),
                course,
                int(round(f.t_fix_s / dt)),
            ]
        )
    with tempfile.TemporaryDirectory() as d:
        imu_path = pathlib.Path(d) / "imu.bin"
        fix_path = pathlib.Path(d) / "fixes.json"
        imu_path.write_bytes(counts.astype("<i2").tobytes())
        fix_path.write_text(json.dumps(fixes))
        lever = [float(x) for x in gnss.model.lever_b_m]
        text = vm.run(
            _SCRIPT.format(
                profile=profile,
                lever=lever,
                slices=slices_per_tick,
                coning=coning,
                imu_path=str(imu_path),
                fix_path=str(fix_path),
            ),
            timeout=timeout,
        )
    lines = text.strip().splitlines()
    out = json.loads(lines[-1])
    blocks = b"".join(bytes.fromhex(ln[2:]) for ln in lines if ln.startswith("B "))
    state = b"".join(bytes.fromhex(ln[2:]) for ln in lines if ln.startswith("S "))
    out["blocks"] = np.frombuffer(blocks, dtype="<u2").astype(int)
    out["state"] = np.frombuffer(state, dtype=np.uint8).astype(int)
    return out
