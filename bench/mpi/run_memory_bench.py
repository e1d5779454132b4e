#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Memory per rank of an MPI run over a large LES scene: one copy of the scene per node.

Makes (once) a synthetic cumulus field of about 1e7 voxels with
bench/broadband/make_cumulus_field.py (400 x 400 columns of 50 m, 64 layers of 46.875 m up to
3 km: 1.02e7 voxels), then runs each given kumo build on 1 and on 2 ranks of this node with few
photons (it is memory that is measured, not speed) and samples every rank's memory every
0.05 s from /proc while it runs:

* VmHWM (/proc/PID/status): the peak resident set, what `/usr/bin/time -v` reports as the
  maximum resident set size. It counts the pages of a shared-memory window in every rank that
  touches them, so it overstates what ranks sharing a window cost the node;
* peak RssAnon (/proc/PID/status): the peak of the rank's private memory;
* peak Pss (/proc/PID/smaps_rollup): the proportional set size, shared pages divided among the
  processes that map them; the peak of the sum over the ranks is what the node needs.

Usage:  python3 bench/mpi/run_memory_bench.py KUMO [KUMO ...] [--work DIR] [--nx 400]
        [--voxel-absorption] [--column-fluxes] [--broadband] [--mpiexec "mpiexec --oversubscribe"]
Prints one line per build, rank count and rank (MiB), then the node's peak.
Needs numpy and netCDF4 (for the field), Linux /proc.
"""

import argparse
import os
import shlex
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(os.path.dirname(HERE))


def field(work, nx):
    path = os.path.join(work, f"cumulus_{nx}.nc")
    if not os.path.exists(path):
        subprocess.run([sys.executable, os.path.join(REPO, "bench", "broadband",
                                                      "make_cumulus_field.py"), path,
                        "--nx", str(nx), "--dx", "50", "--dz", "46.875", "--top", "3000",
                        "--n-clouds", str(max(20, nx * nx // 800)), "--seed", "1"],
                       check=True, stdout=subprocess.DEVNULL)
    return path


def namelist(work, cloud, voxel_absorption, column_fluxes):
    path = os.path.join(work, "memory.nml")
    flag = {True: ".true.", False: ".false."}
    with open(path, "w") as f:
        f.write(f"""&kumo_control n_photons_per_batch = 2000, n_batches = 2, seed = 1 /
&kumo_cloud cloud_file = '{os.path.basename(cloud)}', cloud_format = 'les',
  reff_min_um = 2.0, reff_max_um = 30.0, n_reff = 8, mie_cache = 'mie_table.nc' /
&kumo_atmosphere rayleigh = .true. /
&kumo_surface albedo = 0.05 /
&kumo_source sza_deg = 30.0, wavelength_um = 0.86 /
&kumo_output file = 'memory.nc', voxel_absorption = {flag[voxel_absorption]},
  column_fluxes = {flag[column_fluxes]} /
""")
    return path


def broadband_namelist(work, cloud, voxel_absorption, column_fluxes):
    """A shortwave broadband run over the field (RRTMGP g-points, the cloud's RRTMGP liquid
    optics), levels and humidity above the field as bench/broadband/run_les_broadband_bench.py
    sets them; the k-distribution is found through KUMO_DATA_DIR."""
    import netCDF4
    import numpy as np
    sys.path.insert(0, os.path.join(REPO, "bench", "broadband"))
    from run_les_broadband_bench import example_profile, nml_list
    z_ex, h_ex = example_profile()
    with netCDF4.Dataset(cloud) as f:
        ze = np.array(f["z_edges"][:])
    z = np.concatenate([ze, z_ex[z_ex > ze[-1] + 1.0]])
    zmid = 0.5 * (z[1:] + z[:-1])
    zmid_ex = 0.5 * (z_ex[1:] + z_ex[:-1])
    h = np.exp(np.interp(zmid, zmid_ex, np.log(h_ex)))
    flag = {True: ".true.", False: ".false."}
    path = os.path.join(work, "memory_bb.nml")
    with open(path, "w") as f:
        f.write(f"""&kumo_control n_photons_per_batch = 2000, n_batches = 2, seed = 1 /
&kumo_atmosphere nz = {len(z) - 1}, z_levels = {nml_list(z, '{:.10g}')} /
&kumo_cloud cloud_file = '{os.path.basename(cloud)}', reff_min_um = 2.0, reff_max_um = 30.0 /
&kumo_surface albedo = 0.05 /
&kumo_source sza_deg = 30.0 /
&kumo_output file = 'memory.nc', voxel_absorption = {flag[voxel_absorption]},
  column_fluxes = {flag[column_fluxes]} /
&kumo_spectral kdist_file = 'rrtmgp-gas-sw-g112.nc', profile = 'us1976',
  h2o_vmr = {nml_list(h, '{:.4g}')}, floor_share = 0.2, liquid_optics = 'rrtmgp' /
""")
    return path


def status(pid):
    out = {}
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                key, _, val = line.partition(":")
                if key in ("VmHWM", "RssAnon", "RssShmem"):
                    out[key] = int(val.split()[0])
        with open(f"/proc/{pid}/smaps_rollup") as f:
            for line in f:
                key, _, val = line.partition(":")
                if key == "Pss":
                    out["Pss"] = int(val.split()[0])
    except (FileNotFoundError, ProcessLookupError, PermissionError):
        return None
    return out


def kumo_pids(exe, work):
    """The processes of this run: the given executable, started in the work directory."""
    pids = []
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            if os.path.realpath(f"/proc/{d}/exe") == exe and \
                    os.path.realpath(f"/proc/{d}/cwd") == os.path.realpath(work):
                pids.append(int(d))
        except (FileNotFoundError, PermissionError, ProcessLookupError):
            pass
    return pids


def rank_of(pid):
    try:
        with open(f"/proc/{pid}/environ", "rb") as f:
            for item in f.read().split(b"\0"):
                if item.startswith(b"OMPI_COMM_WORLD_RANK="):
                    return int(item.split(b"=")[1])
    except (FileNotFoundError, PermissionError, ProcessLookupError):
        pass
    return -1


def measure(exe, np, nml, work, mpiexec):
    exe = os.path.realpath(exe)
    cmd = shlex.split(mpiexec) + ["-n", str(np), exe, os.path.basename(nml)]
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    log = open(os.path.join(work, f"run_np{np}.log"), "w")
    proc = subprocess.Popen(cmd, cwd=work, env=env, stdout=log, stderr=subprocess.STDOUT)
    peak = {}      # pid -> dict of peaks
    node_pss = 0
    t0 = time.time()
    while proc.poll() is None:
        total = 0
        for pid in kumo_pids(exe, work):
            s = status(pid)
            if s is None:
                continue
            p = peak.setdefault(pid, {"rank": rank_of(pid)})
            for k, v in s.items():
                p[k] = max(p.get(k, 0), v)
            total += s.get("Pss", 0)
        node_pss = max(node_pss, total)
        time.sleep(0.05)
    if proc.returncode != 0:
        sys.exit(f"run_memory_bench: {' '.join(cmd)} failed, see {log.name}")
    return sorted(peak.values(), key=lambda p: p["rank"]), node_pss, time.time() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("kumo", nargs="+")
    ap.add_argument("--work", default="memory_bench")
    ap.add_argument("--nx", type=int, default=400)
    ap.add_argument("--ranks", default="1,2")
    ap.add_argument("--voxel-absorption", action="store_true",
                    help="per-voxel absorption tallies on (kumo's default; off here)")
    ap.add_argument("--column-fluxes", action="store_true",
                    help="per-column flux maps at every level on (kumo's default; off here)")
    ap.add_argument("--mpiexec", default="mpiexec --oversubscribe")
    ap.add_argument("--broadband", action="store_true",
                    help="a shortwave broadband run (needs KUMO_DATA_DIR with the RRTMGP files)")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    cloud = field(a.work, a.nx)
    if a.broadband:
        nml = broadband_namelist(a.work, cloud, a.voxel_absorption, a.column_fluxes)
    else:
        nml = namelist(a.work, cloud, a.voxel_absorption, a.column_fluxes)
    mib = 1.0 / 1024.0
    print(f"# field {os.path.basename(cloud)}: {a.nx} x {a.nx} x 64 voxels; "
          f"voxel_absorption = {a.voxel_absorption}, column_fluxes = {a.column_fluxes}, "
          f"broadband = {a.broadband}")
    print("# build  ranks  rank  VmHWM  peak_RssAnon  peak_Pss  [MiB]")
    for exe in a.kumo:
        for np in [int(n) for n in a.ranks.split(",")]:
            ranks, node, secs = measure(exe, np, nml, a.work, a.mpiexec)
            for p in ranks:
                print(f"{exe}  {np}  {p['rank']}  {p.get('VmHWM', 0) * mib:.0f}  "
                      f"{p.get('RssAnon', 0) * mib:.0f}  {p.get('Pss', 0) * mib:.0f}")
            print(f"{exe}  {np}  node  peak sum of Pss {node * mib:.0f} MiB  ({secs:.0f} s)")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
