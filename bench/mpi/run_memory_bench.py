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

The runs log at verbose = 2: a build that prints rank 0's memory line (`memory of rank 0: peak
resident set ... after the batches, ... after the output; sums of the tallies ...`) has it
repeated in MiB after its figures, which says whether the output stage (the fold, the products,
the writing) or the batches set rank 0's peak.

`--path` chooses the input path the same field goes through (the voxel optics are alike, the
reading and sharing differ):

* `les` (default): the LES file itself (water content and effective radius, Mie optics);
* `scene`: a scene file (`scene_file`) of extinction 3 LWC / r_e [m-1 for g m-3 and um: the
  geometric-optics extinction efficiency 2] and albedo 0.9999, one Henyey-Greenstein g = 0.85;
* `mcarats`: the same optics as an MCARaTS 3-D atmosphere (float32 binary, one component,
  apf = 0.85, one k-term of absorption perturbation 0, temperature perturbations 0);
* `thermal`: the LES file in a thermal run at 10.5 um that takes the file's temperatures.

Usage:  python3 bench/mpi/run_memory_bench.py KUMO [KUMO ...] [--work DIR] [--nx 400]
        [--voxel-absorption] [--column-fluxes] [--broadband] [--path les|scene|mcarats|thermal]
        [--mpiexec "mpiexec --oversubscribe"]
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
        f.write(f"""&kumo_control n_photons_per_batch = 2000, n_batches = 2, seed = 1, verbose = 2 /
&kumo_cloud cloud_file = '{os.path.basename(cloud)}', cloud_format = 'les',
  reff_min_um = 2.0, reff_max_um = 30.0, n_reff = 8, mie_cache = 'mie_table.nc' /
&kumo_atmosphere rayleigh = .true. /
&kumo_surface albedo = 0.05 /
&kumo_source sza_deg = 30.0, wavelength_um = 0.86 /
&kumo_output file = 'memory.nc', voxel_absorption = {flag[voxel_absorption]},
  column_fluxes = {flag[column_fluxes]} /
""")
    return path


def other_path_namelist(work, cloud, path, voxel_absorption, column_fluxes):
    """The field through another input path (see the module's text): its files (made once)
    and the namelist."""
    import netCDF4
    import numpy as np
    with netCDF4.Dataset(cloud) as f:
        lwc = np.array(f["lwc"][:], dtype=np.float64)          # (z, y, x)
        reff = np.array(f["reff"][:], dtype=np.float64)
        ze = np.array(f["z_edges"][:])
        xs = np.array(f["x"][:])
    nz, ny, nx = lwc.shape
    dx = float(xs[1] - xs[0])
    lx, ly = nx * dx, ny * dx
    ext = np.where(lwc > 0, 3.0 * lwc / np.maximum(reff, 1.0), 0.0)
    flag = {True: ".true.", False: ".false."}
    zl = ", ".join(f"{z:.10g}" for z in ze)
    head = f"""&kumo_control n_photons_per_batch = 2000, n_batches = 2, seed = 1, verbose = 2 /
&kumo_surface albedo = 0.05 /
&kumo_output file = 'memory.nc', voxel_absorption = {flag[voxel_absorption]},
  column_fluxes = {flag[column_fluxes]} /
"""
    out = os.path.join(work, f"memory_{path}.nml")
    if path == "scene":
        scene = os.path.join(work, f"scene_{nx}.nc")
        if not os.path.exists(scene):
            with netCDF4.Dataset(scene, "w") as g:
                for name, n in (("x", nx), ("y", ny), ("z", nz), ("component", 1)):
                    g.createDimension(name, n)
                e = g.createVariable("extinction", "f8", ("component", "z", "y", "x"))
                e.units = "m-1"
                e[:] = ext[None]
                w = g.createVariable("ssa", "f8", ("component", "z", "y", "x"))
                w.units = "1"
                w[:] = np.full((1, nz, ny, nx), 0.9999)
        text = head + f"""&kumo_source sza_deg = 30.0, wavelength_um = 0.86 /
&kumo_atmosphere nz = {nz}, z_levels = {zl}, lx = {lx}, ly = {ly},
  scene_file = '{os.path.basename(scene)}', k3d_bottom = 1, nz3 = {nz}, nx = {nx}, ny = {ny} /
&kumo_phase n_phase = 1, phase_kind = 'hg', phase_g = 0.85 /
"""
    elif path == "mcarats":
        atm = os.path.join(work, f"mca_{nx}.atm")
        if not os.path.exists(atm):
            # Fortran order (x fastest): tmpa3d (nx, ny, nz), absg3d (nx, ny, nz, 1), then
            # extp3d, omgp3d, apfp3d of the component
            with open(atm, "wb") as g:
                zero = np.zeros((nz, ny, nx), dtype="<f4")
                for a in (zero, zero, ext.astype("<f4"),
                          np.full((nz, ny, nx), 0.9999, dtype="<f4"),
                          np.full((nz, ny, nx), 0.85, dtype="<f4")):
                    g.write(a.tobytes())
        text = head + f"""&kumo_source sza_deg = 30.0, wavelength_um = 0.86 /
&kumo_atmosphere nz = {nz}, z_levels = {zl}, lx = {lx}, ly = {ly},
  k3d_bottom = 1, nz3 = {nz}, nx = {nx}, ny = {ny} /
&kumo_cloud cloud_file = '{os.path.basename(atm)}', cloud_format = 'mcarats', mcarats_np3d = 1,
  mcarats_nkd = 1, mcarats_mtprof = 0, mcarats_ikd = 1 /
"""
    else:   # thermal: the LES file with its temperatures, levels of the BOMEX-like column
        with netCDF4.Dataset(cloud) as f:
            t = np.array(f["temperature"][:])
        tl = [float(t[0].mean())] + [float(t[k].mean()) for k in range(nz)]
        text = head + f"""&kumo_source sza_deg = 30.0, wavelength_um = 10.5, solar_flux = 0.0 /
&kumo_cloud cloud_file = '{os.path.basename(cloud)}', cloud_format = 'les',
  reff_min_um = 2.0, reff_max_um = 30.0, n_reff = 8, mie_cache = 'mie_table_10.nc' /
&kumo_thermal t_levels = {", ".join(f"{x:.2f}" for x in tl)}, t_surface = {tl[0]:.2f},
  wavelength_um = 10.5 /
"""
    with open(out, "w") as f:
        f.write(text)
    return out


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
        f.write(f"""&kumo_control n_photons_per_batch = 2000, n_batches = 2, seed = 1, verbose = 2 /
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


def memory_line(work, np):
    """Rank 0's memory line of the run log in MiB (after the batches, after the output, sums of
    the tallies), or None for a build that does not print it."""
    with open(os.path.join(work, f"run_np{np}.log")) as f:
        for line in f:
            if line.startswith("memory of rank 0: "):
                nums = [int(w) for w in line.replace(";", " ").replace(",", " ").split()
                        if w.isdigit()]
                if len(nums) == 3:
                    return [n / 1048576.0 for n in nums]
    return None


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
    ap.add_argument("--path", default="les", choices=["les", "scene", "mcarats", "thermal"],
                    help="the input path of the field (module text)")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    cloud = field(a.work, a.nx)
    if a.broadband:
        nml = broadband_namelist(a.work, cloud, a.voxel_absorption, a.column_fluxes)
    elif a.path != "les":
        nml = other_path_namelist(a.work, cloud, a.path, a.voxel_absorption, a.column_fluxes)
    else:
        nml = namelist(a.work, cloud, a.voxel_absorption, a.column_fluxes)
    mib = 1.0 / 1024.0
    print(f"# field {os.path.basename(cloud)}: {a.nx} x {a.nx} x 64 voxels; "
          f"voxel_absorption = {a.voxel_absorption}, column_fluxes = {a.column_fluxes}, "
          f"broadband = {a.broadband}, path = {a.path}")
    print("# build  ranks  rank  VmHWM  peak_RssAnon  peak_Pss  [MiB]")
    for exe in a.kumo:
        for np in [int(n) for n in a.ranks.split(",")]:
            ranks, node, secs = measure(exe, np, nml, a.work, a.mpiexec)
            for p in ranks:
                print(f"{exe}  {np}  {p['rank']}  {p.get('VmHWM', 0) * mib:.0f}  "
                      f"{p.get('RssAnon', 0) * mib:.0f}  {p.get('Pss', 0) * mib:.0f}")
            print(f"{exe}  {np}  node  peak sum of Pss {node * mib:.0f} MiB  ({secs:.0f} s)")
            mem = memory_line(a.work, np)
            if mem is not None:
                print(f"#   rank 0 VmHWM {mem[0]:.0f} MiB after the batches, {mem[1]:.0f} MiB "
                      f"after the output; sums of the tallies {mem[2]:.0f} MiB")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
