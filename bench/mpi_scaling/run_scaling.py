#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Measure kumo's MPI efficiency from 1 to 2 ranks and the cost of its collective operations.

Parts (``--parts``, default efficiency,collectives):

  efficiency   two workloads at a fixed photon budget, each on 1 rank, on 2 ranks and, as the
               control, two serial runs of half the budget started together (what the two cores
               give with no MPI at all); the three kinds rotate their order from one repetition
               to the next (interleaved). Workloads:
                 hg_slab  Henyey-Greenstein g 0.85 slab, tau 10, omega 0.99, SZA 30 (fluxes),
                          40 batches of 2e5 photons;
                 les      the I3RC LES stratocumulus at 2.13 um (bench/make_les_scene.py) with
                          its namelist's radiances, absorption per voxel and flux maps at every
                          level (kumo's defaults), 24 batches of 1e5 photons.
  collectives  builds kumo_collectives.F90 (beside this script) with mpifort and runs it on 2
               ranks (and, with --oversubscribed, on 4 and 8 ranks with smaller sizes: two
               cores only, so those ranks share them).
  work         serial runs of the LES without radiances (fluxes, flux maps, voxel absorption):
               CPU time per photon and the standard errors from which model.py takes the
               photons a run to 0.1 % (domain reflectance) or to 10 % (median cloudy voxel) needs.
  large        the LES tiled 12 x 12 (9.4e6 voxels), 2 batches of 1000 photons on 1 and 2 ranks:
               set-up, tally work per batch and the end-of-run fold in kumo itself.
  checkpoint   the LES tiled --ckpt-tiles x --ckpt-tiles (default 4: 256 x 256 x 16 voxels, 23 MB
               per slot) on 2 and 4 ranks, 4 batches of 1000 photons per rank, without
               checkpoints and with one after every round of batches (3 per run): the time of
               one checkpoint is the difference of the wall times over 3, alternating the two.

Every run records the wall time kumo reports (and the external one), the CPU time, the set-up
time and the 1-minute load average before and after, as JSON lines in WORK/results.jsonl (or
--results), which model.py reads. Usage:

  python3 bench/mpi_scaling/run_scaling.py --kumo build/kumo --prp les_stcu_w213.prp
      --molec molec_abs_w213.dat --work scaling_runs [--reps 3] [--parts efficiency]
      [--mpirun "mpirun --oversubscribe"] [--oversubscribed]

The .prp and molecular absorption files are those of the I3RC community model
(Tools/Examples), as for bench/make_les_scene.py.
"""
import argparse
import json
import os
import re
import shlex
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(ROOT, 'python', 'src'))   # the kumo package of this tree
import kumo  # noqa: E402

#: Fixed budgets (photons per batch, batches) of the efficiency workloads.
BUDGET = {'hg_slab': (200000, 40), 'les': (100000, 24), 'les_flux': (100000, 24)}


def fortran(v):
    """A scalar as a namelist value."""
    if isinstance(v, bool):
        return '.true.' if v else '.false.'
    if isinstance(v, str):
        return f"'{v}'"
    return str(v)


def loadavg():
    with open('/proc/loadavg') as f:
        return float(f.read().split()[0])


def attrs(path, scene=None):
    """The run's global attributes (times, photons, ranks) of a kumo result file, the domain
    reflectance with its standard error and, with the scene file of an LES run, the median
    relative standard error of the voxel absorption over the cloudy voxels (extinction > 0)."""
    import numpy as np
    from netCDF4 import Dataset
    with Dataset(path) as d:
        r = {k: float(d.getncattr(k)) for k in
             ('wall_time_s', 'cpu_time_s', 'setup_time_s', 'n_photons', 'n_ranks')
             if k in d.ncattrs()}
        r['reflectance'] = float(d['reflectance'][...])
        r['reflectance_stderr'] = float(d['reflectance_stderr'][...])
        if scene and 'absorptance_voxel' in d.variables:
            with Dataset(scene) as sc:
                cloudy = np.asarray(sc['extinction'][0, ...]) > 0.0
            m = np.asarray(d['absorptance_voxel'][...], dtype=float)[cloudy]
            e = np.asarray(d['absorptance_voxel_stderr'][...], dtype=float)[cloudy]
            rel = np.where(m > 0.0, e / np.where(m > 0.0, m, 1.0), np.inf)
            r['cloudy_voxels'] = int(cloudy.sum())
            r['voxel_median_rel_stderr'] = float(np.median(rel))
    return r


class Runner:
    def __init__(self, a):
        self.a = a
        self.work = os.path.abspath(a.work)
        os.makedirs(self.work, exist_ok=True)
        self.results = os.path.join(self.work, 'results.jsonl') if not a.results else a.results
        self.mpirun = shlex.split(a.mpirun)
        self.kumo = os.path.abspath(a.kumo)

    def record(self, rec):
        rec['time'] = time.strftime('%Y-%m-%dT%H:%M:%S')
        with open(self.results, 'a') as f:
            f.write(json.dumps(rec) + '\n')

    # -- namelists --------------------------------------------------------------------------
    def les_text(self):
        """The LES namelist of make_les_scene.py (text; its other groups are kept as written)."""
        if not hasattr(self, '_les'):
            d = os.path.join(self.work, 'les')
            nml = os.path.join(d, 'les_stcu_w213.nml')
            if not os.path.exists(nml):
                cmd = [sys.executable, os.path.join(ROOT, 'bench', 'make_les_scene.py'),
                       '--out-dir', d, '--prp', self.a.prp]
                cmd += ['--molec', self.a.molec] if self.a.molec else ['--no-molecules']
                subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
            with open(nml) as f:
                self._les = f.read()
        return self._les

    def namelist(self, case, name, npb, nb, seed):
        """Write the namelist NAME.nml in the folder of the case's inputs; returns it and the
        output file."""
        control = {'n_photons_per_batch': npb, 'n_batches': nb, 'seed': seed, 'verbose': 0}
        if case == 'hg_slab':
            folder = self.work
            groups = {
                'control': control,
                'atmosphere': {'nz': 1, 'z_levels': [0.0, 1000.0], 'lx': 1000.0, 'ly': 1000.0,
                               'ext1d': [[0.01]], 'ssa1d': [[0.99]], 'phase1d': [[1]]},
                'phase': {'n_phase': 1, 'phase_kind': 'hg', 'phase_g': 0.85},
                'surface': {'albedo': 0.0},
                'source': {'sza_deg': 30.0, 'phi0_deg': 0.0},
                'output': {'file': name + '.nc'},
            }
        else:
            folder = os.path.join(self.work, 'les')
            groups = {'control': control,
                      'output': {'file': name + '.nc', 'voxel_absorption': True,
                                 'column_fluxes': True}}
        path = os.path.join(folder, name + '.nml')
        if case != 'hg_slab':
            # the scene's groups as written, with this run's control and output groups
            keep = re.sub(r'&kumo_(control|output)\b.*?\n/\n', '', self.les_text(),
                          flags=re.DOTALL)
            if case == 'les_flux':   # fluxes and voxel absorption only
                keep = re.sub(r'&kumo_radiance\b.*?\n/\n', '', keep, flags=re.DOTALL)
            text = ''.join(f'&kumo_{g}\n' + ''.join(f'    {k} = {fortran(v)}\n' for k, v in
                                                    groups[g].items()) + '/\n\n'
                           for g in ('control', 'output')) + keep
        else:
            text = str(kumo.to_namelist(groups))
        with open(path, 'w') as f:
            f.write(text)
        return path, os.path.join(folder, name + '.nc')

    def scene(self, case):
        return os.path.join(self.work, 'les', 'les_stcu_w213.nc') if case != 'hg_slab' else None

    # -- efficiency -------------------------------------------------------------------------
    def run_kumo(self, case, kind, rep, ranks):
        npb, nb = BUDGET[case]
        name = f'{case}_{kind}_{rep}'
        nml, out = self.namelist(case, name, npb, nb, seed=3)
        cmd = self.mpirun + ['-np', str(ranks), self.kumo, os.path.basename(nml)]
        la0 = loadavg()
        t0 = time.perf_counter()
        subprocess.run(cmd, cwd=os.path.dirname(nml), check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        rec = dict(part='efficiency', case=case, kind=kind, rep=rep, ranks=ranks,
                   photons_per_batch=npb, batches=nb, external_wall_s=wall, load_before=la0,
                   load_after=loadavg(), **attrs(out, self.scene(case)))
        self.record(rec)
        os.remove(out)
        return rec

    def run_halves(self, case, rep):
        """Two serial runs of half the budget started together (no MPI)."""
        npb, nb = BUDGET[case]
        procs, outs = [], []
        la0 = loadavg()
        t0 = time.perf_counter()
        for half in (0, 1):
            nml, out = self.namelist(case, f'{case}_half{half}_{rep}', npb, nb // 2, 30 + half)
            outs.append(out)
            procs.append(subprocess.Popen([self.kumo, os.path.basename(nml)],
                                          cwd=os.path.dirname(nml), stdout=subprocess.DEVNULL))
        if any(p.wait() for p in procs):
            raise SystemExit('run_scaling: a serial half of the control failed')
        wall = time.perf_counter() - t0
        r = [attrs(o, self.scene(case)) for o in outs]
        rec = dict(part='efficiency', case=case, kind='halves', rep=rep, ranks=1,
                   photons_per_batch=npb, batches=nb, external_wall_s=wall, load_before=la0,
                   load_after=loadavg(), n_photons=sum(x['n_photons'] for x in r),
                   wall_time_s=max(x['wall_time_s'] for x in r),
                   cpu_time_s=sum(x['cpu_time_s'] for x in r),
                   setup_time_s=max(x['setup_time_s'] for x in r))
        self.record(rec)
        for o in outs:
            os.remove(o)
        return rec

    def part_efficiency(self):
        kinds = ['np1', 'np2', 'halves']
        for rep in range(self.a.reps):
            for case in ('hg_slab', 'les'):
                for kind in kinds[rep % 3:] + kinds[:rep % 3]:
                    if kind == 'halves':
                        r = self.run_halves(case, rep)
                    else:
                        r = self.run_kumo(case, kind, rep, int(kind[-1]))
                    print(f'  {case:8s} {kind:6s} rep {rep}: wall {r["wall_time_s"]:.2f} s '
                          f'(external {r["external_wall_s"]:.2f}), cpu {r["cpu_time_s"]:.2f} s, '
                          f'set-up {r["setup_time_s"]:.3f} s, load {r["load_before"]:.2f}/'
                          f'{r["load_after"]:.2f}', flush=True)

    def part_work(self):
        """Serial runs of the LES without radiances (fluxes, flux maps, voxel absorption):
        the CPU time W of the flux run to 0.1 % and of the heating run to 10 % on the median
        cloudy voxel follow from their standard errors (W = cpu (e / target)^2)."""
        for rep in range(self.a.reps):
            r = self.run_kumo('les_flux', 'work', rep, 1)
            print(f'  les_flux serial rep {rep}: cpu {r["cpu_time_s"]:.2f} s, R '
                  f'{r["reflectance"]:.5f} +- {r["reflectance_stderr"]:.5f}, median cloudy voxel '
                  f'relative error {r.get("voxel_median_rel_stderr", float("nan")):.4f}, load '
                  f'{r["load_before"]:.2f}/{r["load_after"]:.2f}', flush=True)

    # -- a large scene, tracing tiny ---------------------------------------------------------
    def large_scene(self, tiles):
        """The LES tiled `tiles` x `tiles` times horizontally (64 t x 64 t x 16 voxels), with
        the namelist of make_les_scene.py adapted to it; returns the namelist text."""
        import numpy as np
        from netCDF4 import Dataset
        d = os.path.join(self.work, 'les')
        self.les_text()
        name = f'les_tiled{tiles}.nc'
        path = os.path.join(d, name)
        if not os.path.exists(path):
            with Dataset(os.path.join(d, 'les_stcu_w213.nc')) as src, Dataset(path, 'w') as dst:
                dst.setncatts({k: src.getncattr(k) for k in src.ncattrs()})
                for dim, n in src.dimensions.items():
                    dst.createDimension(dim, len(n) * (tiles if dim in ('x', 'y') else 1))
                for v in src.variables.values():
                    out = dst.createVariable(v.name, v.dtype, v.dimensions)
                    out.setncatts({k: v.getncattr(k) for k in v.ncattrs()})
                    a = np.asarray(v[...])
                    if v.name in ('x', 'y'):
                        step = a[1] - a[0]
                        a = a[0] + step * np.arange(a.size * tiles)
                    elif v.ndim == 4:
                        a = np.tile(a, (1, 1, tiles, tiles))
                    out[...] = a
        text = self.les_text()
        for key in ('nx', 'ny'):
            text = re.sub(rf'\b{key} = (\d+)',
                          lambda m, key=key: f'{key} = {int(m.group(1)) * tiles}', text)
        for key in ('lx', 'ly'):
            text = re.sub(rf'\b{key} = ([0-9.eE+-]+)',
                          lambda m, key=key: f'{key} = {float(m.group(1)) * tiles}', text)
        return text.replace("'les_stcu_w213.nc'", f"'{name}'")

    def part_large(self):
        """The LES tiled 12 x 12 (768 x 768 x 16 = 9.4e6 voxels) with absorption per voxel and
        flux maps at the bottom and top of the 3-D region (the column budget), 2 batches of 1000
        photons, on 1 and 2 ranks, alternating: the set-up (rank 0 reads, the scene is shared)
        and the end of the run (kumo's reduction of 2 x 1.3e7 doubles per slot) dominate."""
        tiles = 12
        text = self.large_scene(tiles)
        keep = re.sub(r'&kumo_(control|output|radiance)\b.*?\n/\n', '', text, flags=re.DOTALL)
        for rep in range(self.a.reps):
            for ranks in ((1, 2) if rep % 2 == 0 else (2, 1)):
                name = f'large_np{ranks}_{rep}'
                nml = os.path.join(self.work, 'les', name + '.nml')
                with open(nml, 'w') as f:
                    f.write(f'&kumo_control\n    n_photons_per_batch = 1000\n    n_batches = 2\n'
                            f'    seed = 3\n    verbose = 0\n/\n\n&kumo_output\n'
                            f"    file = '{name}.nc'\n    voxel_absorption = .true.\n"
                            f'    column_fluxes = .true.\n    flux_levels = 1, 17\n/\n\n' + keep)
                la0 = loadavg()
                t0 = time.perf_counter()
                subprocess.run(self.mpirun + ['-np', str(ranks), self.kumo, os.path.basename(nml)],
                               cwd=os.path.dirname(nml), check=True, stdout=subprocess.DEVNULL)
                wall = time.perf_counter() - t0
                out = os.path.join(os.path.dirname(nml), name + '.nc')
                r = attrs(out)
                os.remove(out)
                rec = dict(part='large', case=f'les_tiled{tiles}', rep=rep, ranks=ranks,
                           voxels=(64 * tiles) ** 2 * 16, tally_doubles=(64 * tiles) ** 2 * (6 + 16),
                           external_wall_s=wall, load_before=la0, load_after=loadavg(), **r)
                self.record(rec)
                print(f'  large np{ranks} rep {rep}: wall {r["wall_time_s"]:.2f} s, set-up '
                      f'{r["setup_time_s"]:.2f} s, after set-up '
                      f'{r["wall_time_s"] - r["setup_time_s"]:.2f} s, cpu {r["cpu_time_s"]:.2f} s, '
                      f'external {wall:.2f} s, load {la0:.2f}/{rec["load_after"]:.2f}', flush=True)

    # -- checkpoints ------------------------------------------------------------------------
    def part_checkpoint(self):
        """The time of one checkpoint of a large tally (absorption per voxel and flux maps at
        two levels on the tiled LES), on 2 and 4 ranks (oversubscribed on two cores): runs of
        4 P batches without checkpoints and with checkpoint_interval 1e-9 s (a checkpoint after
        batches P, 2P and 3P), alternating."""
        tiles = self.a.ckpt_tiles
        text = self.large_scene(tiles)
        keep = re.sub(r'&kumo_(control|output|radiance)\b.*?\n/\n', '', text, flags=re.DOTALL)
        s_tally = (64 * tiles) ** 2 * (6 + 16)
        for rep in range(self.a.reps):
            for ranks in (2, 4):
                for interval in ((0.0, 1e-9) if rep % 2 == 0 else (1e-9, 0.0)):
                    name = f'ckpt_np{ranks}_{"on" if interval else "off"}_{rep}'
                    nml = os.path.join(self.work, 'les', name + '.nml')
                    with open(nml, 'w') as f:
                        f.write(f'&kumo_control\n    n_photons_per_batch = 1000\n'
                                f'    n_batches = {4 * ranks}\n    seed = 3\n    verbose = 1\n'
                                f'    checkpoint_interval = {interval}\n/\n\n&kumo_output\n'
                                f"    file = '{name}.nc'\n    voxel_absorption = .true.\n"
                                f'    column_fluxes = .true.\n    flux_levels = 1, 17\n/\n\n' + keep)
                    la0 = loadavg()
                    t0 = time.perf_counter()
                    p = subprocess.run(self.mpirun + ['-np', str(ranks), self.kumo,
                                                      os.path.basename(nml)],
                                       cwd=os.path.dirname(nml), check=True, capture_output=True,
                                       text=True)
                    wall = time.perf_counter() - t0
                    out = os.path.join(os.path.dirname(nml), name + '.nc')
                    r = attrs(out)
                    os.remove(out)
                    # the time kumo reports per checkpoint, where it does (per-rank parts)
                    own = [float(m.group(1)) for m in
                           re.finditer(r'checkpoint after batch .* ([0-9.eE+-]+) s\)', p.stderr)]
                    rec = dict(part='checkpoint', case=f'les_tiled{tiles}', rep=rep, ranks=ranks,
                               interval=interval, kumo=self.kumo, tally_doubles=s_tally,
                               reported_checkpoint_s=own, external_wall_s=wall, load_before=la0,
                               load_after=loadavg(), **r)
                    self.record(rec)
                    print(f'  checkpoint np{ranks} interval {interval}: wall {r["wall_time_s"]:.2f} s, '
                          f'external {wall:.2f} s, reported {own}', flush=True)

    # -- collectives ------------------------------------------------------------------------
    def part_collectives(self):
        exe = os.path.join(self.work, 'kumo_collectives')
        subprocess.run(['mpifort', '-O2', '-o', exe, os.path.join(HERE, 'kumo_collectives.F90')],
                       check=True)
        plan = [(2, 10000000, 7)]
        if self.a.oversubscribed:
            plan += [(4, 1000000, 5), (8, 1000000, 5)]
        for ranks, max_doubles, reps in plan:
            la0 = loadavg()
            p = subprocess.run(self.mpirun + ['-np', str(ranks), exe, str(max_doubles), str(reps)],
                               check=True, capture_output=True, text=True)
            la1 = loadavg()
            for line in p.stdout.split('\n'):
                f = line.split()
                if len(f) != 4:
                    continue
                self.record(dict(part='collectives', op=f[0], ranks=int(f[1]), bytes=int(f[2]),
                                 seconds=float(f[3]), oversubscribed=ranks > 2,
                                 load_before=la0, load_after=la1))
            print(p.stdout, end='', flush=True)


def main():
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--kumo', default=os.path.join(ROOT, 'build', 'kumo'))
    p.add_argument('--prp', help='les_stcu_w213.prp of the I3RC community model')
    p.add_argument('--molec', help='molec_abs_w213.dat (else no molecular absorption)')
    p.add_argument('--work', required=True, help='folder for inputs, outputs and results')
    p.add_argument('--results', help='results file (default WORK/results.jsonl)')
    p.add_argument('--reps', type=int, default=3)
    p.add_argument('--parts', default='efficiency,collectives')
    p.add_argument('--mpirun', default='mpirun --oversubscribe')
    p.add_argument('--oversubscribed', action='store_true',
                   help='also time the collectives on 4 and 8 ranks (more ranks than cores)')
    p.add_argument('--ckpt-tiles', type=int, default=4,
                   help='tiles per side of the LES for the checkpoint part')
    a = p.parse_args()
    r = Runner(a)
    parts = a.parts.split(',')
    if set(parts) & {'efficiency', 'work', 'large', 'checkpoint'} and not a.prp:
        p.error('--prp is needed for the LES workload')
    if 'collectives' in parts:
        r.part_collectives()
    if 'efficiency' in parts:
        r.part_efficiency()
    if 'work' in parts:
        r.part_work()
    if 'large' in parts:
        r.part_large()
    if 'checkpoint' in parts:
        r.part_checkpoint()


if __name__ == '__main__':
    main()
