#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Run the kumo performance benchmark cases and log one JSON record per run.

Called by bench/run_bench.sh, which builds kumo and then runs bench/analyse_bench.py on the log.
Every run writes its namelist and netCDF output into the raw folder (bench/results/raw by
default, not kept in git) and appends a record to <raw>/runs.jsonl with the figures the analysis
needs: photon count, CPU and wall time (from the output's global attributes), the means and
standard errors of the domain outputs, the load average before and after, and for the Landsat
cloud the statistics of the voxel absorption.

Parts (--parts, comma-separated; default all):
  fom         increasing photon counts for each case (figure of merit per output)
  target      one direct run per case with the stopping rule target_rel_error = 0.001
  resolution  Landsat 128 x 128 against the same field on 256 x 256, super-voxels on and off,
              interleaved, side by side
  callgrind   instruction counts per photon of the same four configurations (valgrind)
  cachesim    simulated memory reads per photon, 128 x 128 against 256 x 256 (valgrind)
  mpi         a fixed photon budget of the HG slab on 1 and on 2 MPI ranks, interleaved, and as a
              control two serial runs of half the budget started together
"""
import argparse
import json
import os
import resource
import shlex
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), 'python', 'src'))   # the kumo package
import kumo  # noqa: E402

# ------------------------------------------------------------------------------------------------
# Cases
# ------------------------------------------------------------------------------------------------

#: Plane-parallel slabs: (title, optical depth, single-scattering albedo, phase group, sza, albedo)
SLABS = {
    'mcpp_slab': dict(title='isotropic slab, tau 2, omega 0.99, SZA 60, Lambert albedo 0.2',
                      tau=2.0, ssa=0.99, phase={'phase_kind': 'isotropic'}, sza=60.0,
                      albedo=0.2),
    'hg_slab': dict(title='Henyey-Greenstein g 0.85 slab, tau 10, omega 0.99, SZA 30, '
                          'black surface',
                    tau=10.0, ssa=0.99, phase={'phase_kind': 'hg', 'phase_g': 0.85}, sza=30.0,
                    albedo=0.0),
}
LANDSAT_TITLE = ('I3RC Landsat cloud (case 3), 128 x 128 x 20 voxels, HG g 0.85, omega 0.99, '
                 'SZA 60, black surface')

#: Photons per batch of the figure-of-merit series (each run has N_BATCHES batches).
N_BATCHES = 20
FOM_SERIES = {
    'mcpp_slab': [10000, 30000, 100000, 300000, 1000000],
    'hg_slab': [10000, 30000, 100000, 300000, 1000000],
    'landsat': [5000, 15000, 50000, 150000],
}
QUICK_SERIES = {
    'mcpp_slab': [2000, 10000],
    'hg_slab': [2000, 10000],
    'landsat': [1000, 4000],
}


def control_group(npb, nb, seed=1, target=0.0):
    group = {'n_photons_per_batch': npb, 'n_batches': nb, 'seed': seed, 'verbose': 0}
    if target > 0.0:
        group.update(target_rel_error=target, target_output='reflectance')
    return group


def slab_namelist(case, out, npb, nb, seed=1, target=0.0):
    """Namelist groups (kumo.write_namelist) of a plane-parallel slab case."""
    c = SLABS[case]
    depth = 1000.0
    return {
        'control': control_group(npb, nb, seed, target),
        'atmosphere': {'nz': 1, 'z_levels': [0.0, depth], 'lx': 1000.0, 'ly': 1000.0,
                       'ext1d': [[c['tau'] / depth]], 'ssa1d': [[c['ssa']]], 'phase1d': [[1]]},
        'phase': {'n_phase': 1, **c['phase']},
        'surface': {'albedo': c['albedo']},
        'source': {'sza_deg': c['sza'], 'phi0_deg': 0.0},
        'output': {'file': out},
    }


def landsat_namelist(atm_group, out, npb, nb, seed=1, target=0.0, supervoxels=True):
    """Namelist groups of the Landsat case; `atm_group` is its &kumo_atmosphere group (a dict,
    as make_landsat_scene.py --atm-group writes it)."""
    return {
        'control': control_group(npb, nb, seed, target),
        'atmosphere': atm_group,
        'phase': {'n_phase': 1, 'phase_kind': 'hg', 'phase_g': 0.85},
        'surface': {'albedo': 0.0},
        'source': {'sza_deg': 60.0, 'phi0_deg': 0.0},
        'output': {'file': out, 'flux_levels': [0, atm_group['nz']], 'column_fluxes': True,
                   'voxel_absorption': True},
        'vr': {'use_supervoxels': supervoxels},
    }


# ------------------------------------------------------------------------------------------------
# Running and reading
# ------------------------------------------------------------------------------------------------

def loadavg():
    try:
        with open('/proc/loadavg') as f:
            return float(f.read().split()[0])
    except OSError:
        return float('nan')


def read_output(path, voxel=False):
    """Global attributes and the domain outputs of a kumo result file."""
    from netCDF4 import Dataset
    import numpy as np
    r = {}
    with Dataset(path) as nc:
        for a in ('cpu_time_s', 'wall_time_s', 'setup_time_s', 'n_photons', 'n_batches',
                  'n_ranks'):
            r[a] = float(nc.getncattr(a))
        r['supervoxel_grid'] = str(nc.getncattr('supervoxels'))
        for name in ('reflectance', 'transmittance', 'absorptance_atmosphere'):
            r[name] = float(nc[name][...])
            r[name + '_stderr'] = float(nc[name + '_stderr'][...])
        if voxel and 'absorptance_voxel' in nc.variables:
            m = np.asarray(nc['absorptance_voxel'][...], dtype=float)
            e = np.asarray(nc['absorptance_voxel_stderr'][...], dtype=float)
            hit = m > 0.0
            rel = e[hit] / m[hit]
            r['voxel_n_absorbing'] = int(hit.sum())
            r['voxel_n'] = int(m.size)
            r['voxel_mean_rel_stderr'] = float(rel.mean()) if rel.size else float('nan')
            r['voxel_median_rel_stderr'] = float(np.median(rel)) if rel.size else float('nan')
    return r


def run(cmd, cwd, log):
    """Run a command, return (external wall time, CPU time of the children)."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                       check=False)
    t1 = time.perf_counter()
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    with open(log, 'a') as f:
        f.write('$ ' + ' '.join(shlex.quote(c) for c in cmd) + '\n' + p.stdout)
    if p.returncode != 0:
        sys.stderr.write(p.stdout[-3000:])
        raise SystemExit(f'run_cases: command failed ({p.returncode}): {" ".join(cmd)}')
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return t1 - t0, cpu, p.stdout


class Bench:
    def __init__(self, args):
        self.a = args
        self.raw = os.path.abspath(args.raw)
        os.makedirs(self.raw, exist_ok=True)
        self.runs = os.path.join(self.raw, 'runs.jsonl')
        self.log = os.path.join(self.raw, 'runs.log')
        if not args.append:
            for f in (self.runs, self.log):
                if os.path.exists(f):
                    os.remove(f)
        self.kumo = os.path.abspath(args.kumo)
        self.mpirun = shlex.split(args.mpirun)
        self.atm = {}
        self.session = time.strftime('%Y-%m-%dT%H:%M:%S')

    def record(self, rec):
        rec = dict(rec, session=self.session)
        with open(self.runs, 'a') as f:
            f.write(json.dumps(rec) + '\n')

    def scenes(self):
        """Write the 128 x 128 and 256 x 256 Landsat scenes (once)."""
        for refine, n in ((1, 128), (2, 256)):
            scene = os.path.join(self.raw, f'landsat{n}.nc')
            group = os.path.join(self.raw, f'landsat{n}.atm.nml')
            if not (os.path.exists(scene) and os.path.exists(group)):
                cmd = [sys.executable, os.path.join(HERE, 'make_landsat_scene.py'),
                       '--out', scene, '--refine', str(refine), '--atm-group', group]
                if self.a.data:
                    cmd += ['--data', self.a.data]
                subprocess.run(cmd, check=True)
            self.atm[n] = kumo.read_namelist(group)['atmosphere']

    def namelist(self, case, name, npb, nb, seed=1, target=0.0, supervoxels=True):
        out = name + '.nc'
        if case in SLABS:
            title = SLABS[case]['title']
            groups = slab_namelist(case, out, npb, nb, seed, target)
        else:
            n = 256 if case == 'landsat256' else 128
            title = LANDSAT_TITLE
            groups = landsat_namelist(self.atm[n], out, npb, nb, seed, target, supervoxels)
        path = os.path.join(self.raw, name + '.nml')
        with open(path, 'w') as f:
            f.write(f'! kumo benchmark: {title}\n')
            kumo.to_namelist(groups).write(f)
        return path, os.path.join(self.raw, out)

    def kumo_run(self, part, case, name, npb, nb, seed=1, target=0.0, supervoxels=True,
                 ranks=0, extra=None):
        nml, out = self.namelist(case, name, npb, nb, seed, target, supervoxels)
        cmd = [self.kumo, os.path.basename(nml)]
        if ranks > 0:
            cmd = self.mpirun + ['-np', str(ranks)] + cmd
        la0 = loadavg()
        wall, cpu, _ = run(cmd, self.raw, self.log)
        la1 = loadavg()
        rec = dict(part=part, case=case, name=name, photons_per_batch=npb, batches_per_round=nb,
                   seed=seed, target_rel_error=target, supervoxels=supervoxels,
                   mpi_ranks_requested=ranks, external_wall_s=wall, process_cpu_s=cpu,
                   load_before=la0, load_after=la1, time=time.strftime('%Y-%m-%dT%H:%M:%S'))
        rec.update(read_output(out, voxel=case.startswith('landsat')))
        if extra:
            rec.update(extra)
        self.record(rec)
        print(f'  {name}: {int(rec["n_photons"])} photons, cpu {rec["cpu_time_s"]:.2f} s, '
              f'wall {rec["wall_time_s"]:.2f} s, R {rec["reflectance"]:.5f} +- '
              f'{rec["reflectance_stderr"]:.5f}, load {la0:.2f}/{la1:.2f}', flush=True)
        if not self.a.keep:
            os.remove(out)
        return rec

    # --- parts ----------------------------------------------------------------------------------

    def part_fom(self):
        series = QUICK_SERIES if self.a.quick else FOM_SERIES
        for case in ('mcpp_slab', 'hg_slab', 'landsat'):
            print(f'fom: {case}', flush=True)
            for i, npb in enumerate(series[case]):
                self.kumo_run('fom', case, f'fom_{case}_{npb}', npb, N_BATCHES, seed=100 + i)

    def part_target(self):
        # rounds of 20 batches; small batches so that the run stops close to the target
        plan = {'mcpp_slab': 5000, 'hg_slab': 5000, 'landsat': 5000}
        if self.a.quick:
            plan = {k: 1000 for k in plan}
        target = 0.01 if self.a.quick else 0.001
        for case, npb in plan.items():
            print(f'target: {case}', flush=True)
            self.kumo_run('target', case, f'target_{case}', npb, N_BATCHES, seed=7, target=target)

    def part_resolution(self):
        # short runs (4 batches of 5e4 photons, 1-3 s), many repetitions: the speed of the
        # machine drifts over seconds, so the two runs of a pair should be close in time
        npb, nb, reps = (50000, 4, 8) if not self.a.quick else (2000, 2, 2)
        configs = [('landsat', True), ('landsat256', True), ('landsat', False),
                   ('landsat256', False)]
        print('resolution: 128 x 128 vs 256 x 256, interleaved', flush=True)
        for rep in range(reps):
            # order A B A' B' on even repetitions, B A B' A' on odd ones: a slow drift of the
            # machine's speed cancels in the median of the pair ratios
            order = configs if rep % 2 == 0 else [configs[1], configs[0], configs[3], configs[2]]
            for case, sv in order:
                self.kumo_run('resolution', case, f'res_{case}_sv{int(sv)}_{rep}', npb, nb,
                              seed=11, supervoxels=sv, extra=dict(rep=rep))

    def part_callgrind(self):
        valgrind = self.a.valgrind
        if subprocess.run(['sh', '-c', f'command -v {shlex.quote(valgrind)}'],
                          stdout=subprocess.DEVNULL, check=False).returncode != 0:
            print('callgrind: valgrind not found, skipped', flush=True)
            return
        small, big = (1000, 6000) if not self.a.quick else (200, 600)
        configs = [('landsat', True), ('landsat256', True), ('landsat', False),
                   ('landsat256', False), ('hg_slab', True)]
        print('callgrind: instructions per photon (difference of two photon counts)', flush=True)
        for case, sv in configs:
            irs = {}
            for npb in (small, big):
                name = f'cg_{case}_sv{int(sv)}_{npb}'
                nml, out = self.namelist(case, name, npb, 2, seed=11, supervoxels=sv)
                cg = os.path.join(self.raw, name + '.callgrind')
                cmd = [valgrind, '--tool=callgrind', f'--callgrind-out-file={os.path.basename(cg)}',
                       self.kumo, os.path.basename(nml)]
                run(cmd, self.raw, self.log)
                irs[npb] = callgrind_totals(cg)
                if not self.a.keep:
                    os.remove(out)
            ir_photon = (irs[big]['Ir'] - irs[small]['Ir']) / (2.0 * (big - small))
            ir_trace = (irs[big]['trace'] - irs[small]['trace']) / (2.0 * (big - small))
            fs, fb = irs[small]['functions'], irs[big]['functions']
            per_fn = {fn: (fb.get(fn, 0) - fs.get(fn, 0)) / (2.0 * (big - small))
                      for fn in set(fs) | set(fb)}
            top = sorted(((fn, v) for fn, v in per_fn.items() if v > 0), key=lambda x: -x[1])
            rec = dict(part='callgrind', case=case, supervoxels=sv, photons_small=2 * small,
                       photons_big=2 * big, ir_total_small=irs[small]['Ir'],
                       ir_total_big=irs[big]['Ir'], ir_per_photon=ir_photon,
                       ir_trace_batch_per_photon=ir_trace, functions_per_photon=top[:15])
            self.record(rec)
            print(f'  {case} supervoxels={sv}: {ir_photon:.0f} instructions per photon',
                  flush=True)

    def part_cachesim(self):
        """Simulated last-level-cache misses per photon, 128 x 128 against 256 x 256.

        valgrind models two cache levels; the last level is set to the L3 of the benchmark
        machine (32 MiB, 16-way, 64-byte lines) so that the number does not depend on what the
        host reports. Misses there are reads from memory.
        """
        valgrind = self.a.valgrind
        if subprocess.run(['sh', '-c', f'command -v {shlex.quote(valgrind)}'],
                          stdout=subprocess.DEVNULL, check=False).returncode != 0:
            print('cachesim: valgrind not found, skipped', flush=True)
            return
        small, big = (2000, 12000) if not self.a.quick else (200, 600)
        ll = '33554432,16,64'
        print(f'cachesim: memory reads per photon (simulated last-level cache {ll})', flush=True)
        for case in ('landsat', 'landsat256'):
            ev = {}
            for npb in (small, big):
                name = f'cs_{case}_{npb}'
                nml, out = self.namelist(case, name, npb, 2, seed=11)
                cg = os.path.join(self.raw, name + '.callgrind')
                cmd = [valgrind, '--tool=callgrind', '--cache-sim=yes', f'--LL={ll}',
                       f'--callgrind-out-file={os.path.basename(cg)}', self.kumo,
                       os.path.basename(nml)]
                run(cmd, self.raw, self.log)
                ev[npb] = callgrind_events(cg)
                if not self.a.keep:
                    os.remove(out)
            per = {k: (ev[big][k] - ev[small][k]) / (2.0 * (big - small)) for k in ev[big]}
            rec = dict(part='cachesim', case=case, ll=ll, per_photon=per)
            self.record(rec)
            print(f'  {case}: {per.get("Ir", 0):.0f} instructions, {per.get("D1mr", 0):.1f} L1 '
                  f'read misses, {per.get("DLmr", 0):.2f} memory reads per photon', flush=True)

    def part_mpi(self):
        npb, nb, reps = (200000, 40, 4) if not self.a.quick else (5000, 4, 1)
        print('mpi: fixed budget of the HG slab on 1 and 2 ranks, interleaved, and two serial '
              'halves at once (what the two cores give)', flush=True)
        kinds = ['np1', 'np2', 'halves']
        for rep in range(reps):
            for kind in kinds[rep % 3:] + kinds[:rep % 3]:
                if kind == 'halves':
                    self.halves_run(npb, nb // 2, rep)
                else:
                    ranks = int(kind[-1])
                    self.kumo_run('mpi', 'hg_slab', f'mpi_np{ranks}_{rep}', npb, nb, seed=3,
                                  ranks=ranks, extra=dict(rep=rep, kind=kind))

    def halves_run(self, npb, nb, rep):
        """Two independent serial runs of half the budget, started together: the wall time the
        two cores of the machine allow for the full budget, with no MPI at all."""
        procs, outs = [], []
        la0 = loadavg()
        t0 = time.perf_counter()
        for half in (0, 1):
            name = f'mpi_half{half}_{rep}'
            nml, out = self.namelist('hg_slab', name, npb, nb, seed=30 + half)
            outs.append(out)
            procs.append(subprocess.Popen([self.kumo, os.path.basename(nml)], cwd=self.raw,
                                          stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT))
        codes = [p.wait() for p in procs]
        wall = time.perf_counter() - t0
        la1 = loadavg()
        if any(codes):
            raise SystemExit(f'run_cases: a serial half of the MPI control failed: {codes}')
        r = [read_output(o) for o in outs]
        rec = dict(part='mpi', case='hg_slab', name=f'mpi_halves_{rep}', kind='halves', rep=rep,
                   photons_per_batch=npb, batches_per_round=nb, external_wall_s=wall,
                   load_before=la0, load_after=la1, n_ranks=1.0,
                   n_photons=sum(x['n_photons'] for x in r),
                   wall_time_s=max(x['wall_time_s'] for x in r),
                   cpu_time_s=sum(x['cpu_time_s'] for x in r),
                   reflectance=r[0]['reflectance'], reflectance_stderr=r[0]['reflectance_stderr'],
                   time=time.strftime('%Y-%m-%dT%H:%M:%S'))
        self.record(rec)
        print(f'  mpi_halves_{rep}: 2 x {int(r[0]["n_photons"])} photons at once, cpu '
              f'{rec["cpu_time_s"]:.2f} s, wall {rec["wall_time_s"]:.2f} s, load '
              f'{la0:.2f}/{la1:.2f}', flush=True)
        if not self.a.keep:
            for o in outs:
                os.remove(o)


def callgrind_events(path):
    """Program totals of every event recorded in a callgrind file."""
    names, totals = [], []
    with open(path) as f:
        for line in f:
            if line.startswith('events:'):
                names = line.split()[1:]
            elif line.startswith(('totals:', 'summary:')):
                totals = [int(x) for x in line.split()[1:]]
    return dict(zip(names, totals, strict=True))


def callgrind_totals(path):
    """Total Ir, the inclusive Ir of trace_batch and the self Ir of every function."""
    out = subprocess.run(['callgrind_annotate', '--inclusive=yes', path], stdout=subprocess.PIPE,
                         text=True, check=True).stdout
    out_self = subprocess.run(['callgrind_annotate', path], stdout=subprocess.PIPE, text=True,
                              check=True).stdout
    total = None
    trace = 0
    for line in out.splitlines():
        parts = line.split()
        if not parts:
            continue
        if 'PROGRAM TOTALS' in line:
            total = int(parts[0].replace(',', ''))
        elif 'trace_batch' in line and parts[0].replace(',', '').isdigit():
            trace = max(trace, int(parts[0].replace(',', '')))
    funcs = {}
    for line in out_self.splitlines():
        parts = line.split()
        if len(parts) >= 3 and parts[0].replace(',', '').isdigit() and ':' in line:
            if 'PROGRAM TOTALS' in line:
                continue
            fn = line.split(':', 1)[1].split(' [')[0].strip()
            funcs[fn] = funcs.get(fn, 0) + int(parts[0].replace(',', ''))
    return dict(Ir=total, trace=trace, functions=funcs)


def git_commit():
    """Short hash of the checked-out commit, '+' if the work tree differs from it."""
    repo = os.path.dirname(HERE)
    try:
        h = subprocess.run(['git', '-C', repo, 'rev-parse', '--short', 'HEAD'],
                           stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                           check=True).stdout.strip()
        dirty = subprocess.run(['git', '-C', repo, 'status', '--porcelain', '--untracked-files=no',
                                'src'], stdout=subprocess.PIPE, text=True,
                               check=False).stdout.strip()
        return h + ('+' if dirty else '')
    except (OSError, subprocess.CalledProcessError):
        return 'unknown'


def caches():
    """Cache sizes as lscpu reports them (empty if lscpu is missing)."""
    try:
        out = subprocess.run(['lscpu'], stdout=subprocess.PIPE, text=True, check=False).stdout
    except OSError:
        return ''
    return '; '.join(' '.join(ln.split()) for ln in out.splitlines()
                     if ln.strip().startswith(('L1d', 'L2', 'L3')))


def main():
    ap = argparse.ArgumentParser(description='Run the kumo performance benchmark cases.')
    ap.add_argument('--kumo', required=True, help='the kumo program')
    ap.add_argument('--raw', default=os.path.join(HERE, 'results', 'raw'),
                    help='folder for namelists, outputs and the run log')
    ap.add_argument('--data', default=None, help='folder with the I3RC scene43.* files')
    ap.add_argument('--mpirun', default='mpirun --allow-run-as-root --oversubscribe',
                    help='MPI launcher (without -np)')
    ap.add_argument('--valgrind', default='valgrind')
    ap.add_argument('--parts', default='fom,target,resolution,callgrind,cachesim,mpi')
    ap.add_argument('--commit', default=None,
                    help='commit the kumo program was built from (default: the checked-out one)')
    ap.add_argument('--quick', action='store_true', help='tiny photon counts (smoke test)')
    ap.add_argument('--append', action='store_true', help='append to an existing run log')
    ap.add_argument('--keep', action='store_true', help='keep the netCDF outputs')
    a = ap.parse_args()
    b = Bench(a)
    b.record(dict(part='meta', time=time.strftime('%Y-%m-%dT%H:%M:%S'),
                  commit=a.commit or git_commit(),
                  quick=a.quick, parts=a.parts, caches=caches()))
    b.scenes()
    for part in a.parts.split(','):
        getattr(b, 'part_' + part.strip())()


if __name__ == '__main__':
    main()
