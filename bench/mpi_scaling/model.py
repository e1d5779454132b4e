#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""A scaling model of kumo on P = 1 .. 1000 MPI ranks, from the measurements of run_scaling.py.

    T(P) = T_setup + T_bcast(P, S_in) + ceil(B / P) t_batch (1 + imbalance(P))
           + R T_allreduce(P, 3 P doubles) + T_final(P, S) ,     efficiency E = W / (P T(P))

* W = N c_ph: the CPU time of the photons alone (N photons, c_ph seconds each, measured on one
  rank); t_batch = n_b c_ph + S c_tally: a batch traces n_b photons, then clears its tally and
  adds it to the slot's sums (S doubles, c_tally seconds each, measured on the large scene).
* B batches: as many as the serial run would use (batches of 1e5 photons), but at least one per
  rank (the batches then shrink to N / P photons). R rounds, each ended by the allreduce of the
  target-error decision (3 doubles per slot); a fixed budget has no round allreduce.
* imbalance: the slowest of P ranks at the end of each round; the time of a batch of n_b photons
  has a relative spread cv / sqrt(n_b) (cv: the relative spread of the cost of one photon,
  taken as 1), and the expected maximum of P such times is about sqrt(2 ln P) spreads above the
  mean (normal extremes). Operating-system noise is not included.
* T_final: the end of the run. Today (fold_slots) every rank in turn sends its S1 and S2
  (2 S doubles) to rank 0, which adds them: (P - 1) (2 alpha + 16 S (beta + gamma)), linear in
  P. The alternative: a fixed binary tree over the slots (deterministic, as the slot order is
  today): ceil(log2 P) (alpha + 16 S (beta + gamma)), or pipelined in segments of 64 KiB:
  (ceil(log2 P) + 16 S / s - 1) (alpha + s (beta + gamma)) (Thakur, Rabenseifner and Gropp 2005).
  The small end-of-run reductions (counts, the per-batch records: 24 B bytes) take a binomial
  tree.
* T_bcast: Open MPI's tuned broadcast takes a segmented pipeline or a split binary tree for
  messages of megabytes (ompi/mca/coll/tuned, decision rules of the fixed table); modelled as
  the best of binomial, scatter + allgather (van de Geijn) and a chain pipeline of 128 KiB
  segments (Thakur et al. 2005, Table 1 forms).
* Network: 'here' = alpha, beta fitted to the ping-pong on this machine (shared memory);
  'HDR' = alpha 2 us, beta 1 / (20 GB/s) (HDR InfiniBand: 200 Gb/s links, i.e. 25 GB/s, and
  MPI small-message latencies of 1-2 us as published with the OSU micro-benchmarks);
  'slow' = alpha 8 us, beta 1 / (5 GB/s), a four-times-worse network as a sensitivity check.
  gamma (adding doubles at rank 0, memory bound) is measured here in every case.
* Launching the job (mpirun, process start, MPI_Init) is not part of T: kumo's wall time starts
  after MPI_Init.
* A checkpoint (not part of T: one every checkpoint_interval) holds every slot: 16 S + 88 bytes
  each. Written by rank 0 alone (format 1, kumo before per-rank parts): the P - 1 other slots
  travel to rank 0 one after the other and rank 0 writes all P from one client:
  (P - 1) (3 alpha + m beta) + P m / min(client, FS). Written per rank (format 2): every rank
  writes its own part at once, limited by the nodes' clients and by the file system's aggregate
  bandwidth: max(P m / FS, r m / client) with r ranks per node, plus 3 P metadata operations
  (create, rename, remove of the previous generation) at the metadata server's rate, and a
  few small collectives. The file-system figures are assumptions, not measured here (FS_ASSUMED).

Usage: python3 bench/mpi_scaling/model.py RESULTS.jsonl [RESULTS.jsonl ...] [--markdown]
"""
import argparse
import json
import math
import statistics as st

NETWORKS = {'HDR': (2.0e-6, 1.0 / 20.0e9), 'slow': (8.0e-6, 1.0 / 5.0e9)}
#: Messages up to this size [B] travel at the in-cache rate on this machine, larger ones at the
#: memory rate.
CACHE_BYTES = 8 * 1024 * 1024


def beta_of(small, large=None):
    """Inverse bandwidth [s/B] as a function of the size of the whole buffer moved (on this
    machine a buffer beyond the cache moves at the memory rate, whatever its segments)."""
    large = small if large is None else large
    return lambda m: small if m <= CACHE_BYTES else large
P_LIST = [1, 2, 4, 10, 32, 100, 316, 1000]
#: Parallel file system for checkpoints at scale (assumptions): aggregate write bandwidth [B/s]
#: of a mid-size cluster's scratch file system (the Lustre Operations Manual, 1.1.1 "Lustre
#: Features", lists production systems at 10 TB/s aggregate and one client at 15 GB/s on HDR
#: InfiniBand), one node's write bandwidth [B/s], file creations, renames or removals per second
#: on the metadata server, ranks per node.
FS_ASSUMED = {'FS 100 GB/s': (100e9, 5e9, 20000.0, 64), 'FS 10 GB/s': (10e9, 2e9, 5000.0, 64)}
#: Bytes per slot beyond S1 and S2: its counts (batches, photons, work, anomalies).
SLOT_EXTRA = 88
SEGMENT = 64 * 1024
BCAST_SEGMENT = 128 * 1024


def lsq(xs, ys):
    """Least-squares line y = a + b x."""
    mx, my = st.mean(xs), st.mean(ys)
    b = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)
    return my - b * mx, b


def lg(p):
    return math.ceil(math.log2(p)) if p > 1 else 0


# ---- collective costs ---------------------------------------------------------------------
def t_bcast(p, m, a, b):
    if p == 1:
        return 0.0
    binomial = lg(p) * (a + m * b(m))
    vdg = (lg(p) + p - 1) * a + 2.0 * (p - 1) / p * m * b(m)
    nseg = max(1, math.ceil(m / BCAST_SEGMENT))
    seg = m / nseg
    pipeline = (p - 2 + nseg) * (a + seg * b(m))
    return min(binomial, vdg, pipeline)


def t_fold_today(p, s, a, b, g):
    """fold_slots: P - 1 ranks in turn send 2 S doubles to rank 0, which adds them."""
    return (p - 1) * (2.0 * a + 16.0 * s * (b(16.0 * s) + g))


def t_fold_tree(p, s, a, b, g):
    """A fixed binary tree over the slots, whole arrays or pipelined in segments."""
    if p == 1:
        return 0.0
    m = 16.0 * s
    whole = lg(p) * (a + m * (b(m) + g))
    nseg = max(1, math.ceil(m / SEGMENT))
    seg = m / nseg
    piped = (lg(p) + nseg - 1) * (a + seg * (b(m) + g))
    return min(whole, piped)


def t_allreduce(p, m, a, b, g):
    if p == 1:
        return 0.0
    recursive_doubling = lg(p) * (a + m * (b(m) + g))
    rabenseifner = 2.0 * lg(p) * a + 2.0 * (p - 1) / p * m * b(m) + (p - 1) / p * m * g
    return min(recursive_doubling, rabenseifner)


def t_reduce_small(p, m, a, b, g):
    return lg(p) * (a + m * (b(m) + g))


def t_ckpt_rank0(p, s, a, b, fs):
    """A checkpoint written by rank 0 alone: every other slot moved to it, then written."""
    fs_bw, client, meta, _ = fs
    m = 16.0 * s + SLOT_EXTRA
    return (p - 1) * (3.0 * a + m * b(m)) + p * m / min(client, fs_bw) + 2.0 / meta


def t_ckpt_parts(p, s, a, b, fs):
    """A checkpoint written per rank: all parts at once, then rank 0's small manifest."""
    fs_bw, client, meta, per_node = fs
    m = 16.0 * s + SLOT_EXTRA
    write = max(p * m / fs_bw, min(p, per_node) * m / client)
    small = 4.0 * lg(p) * a   # records to rank 0, the generation, two agreements
    return write + (3.0 * p + 4.0) / meta + small


# ---- measurements -------------------------------------------------------------------------
def load(paths):
    recs = []
    for i, path in enumerate(paths):
        with open(path) as f:
            recs += [dict(json.loads(line), file=i) for line in f if line.strip()]
    return recs


def local_network(recs):
    pp = sorted(collective(recs, 'pingpong', 2).items())
    alpha = st.median([t for m, t in pp if m <= 64])
    small = [(m, t) for m, t in pp if 65536 <= m <= 4194304]
    large = [(m, t) for m, t in pp if m >= 16777216]
    beta_cache = lsq(*zip(*small))[1]
    beta_mem = lsq(*zip(*large))[1]
    return alpha, beta_cache, beta_mem


def collective(recs, op, ranks):
    """Message size [B] -> time [s] of an operation: the fastest of the sessions (each already
    the median of its repetitions), the one least disturbed by the host's other work."""
    best = {}
    for r in recs:
        if r['part'] == 'collectives' and r['op'] == op and r['ranks'] == ranks:
            best[r['bytes']] = min(best.get(r['bytes'], math.inf), r['seconds'])
    return best


def gamma_from_fold(recs, alpha, beta):
    """Seconds per byte of rank 0's additions: the fold on 2 ranks beyond its messages, at the
    largest sizes (never below 0)."""
    fold = collective(recs, 'fold', 2)
    big = sorted(fold)[-2:]
    return max(0.0, st.mean((fold[m] - 2 * alpha - m * beta) / m for m in big))


def median_of(recs, **sel):
    def ok(r):
        return all(r.get(k) == v for k, v in sel.items())
    return [r for r in recs if ok(r)]


# ---- the model ----------------------------------------------------------------------------
class Workload:
    def __init__(self, name, n_photons, c_ph, s_tally, s_in, t_setup, rounds, batch=100000):
        self.name, self.n, self.c_ph, self.s, self.s_in = name, n_photons, c_ph, s_tally, s_in
        self.t_setup, self.rounds, self.batch = t_setup, rounds, batch

    def time(self, p, a, b, g, c_tally, fold='today', cv=1.0):
        b_serial = max(1, math.ceil(self.n / self.batch))
        n_batches = max(b_serial, p)
        n_b = self.n / n_batches
        t_batch = n_b * self.c_ph + self.s * c_tally
        spread = cv / math.sqrt(n_b) * math.sqrt(2.0 * math.log(p)) if p > 1 else 0.0
        compute = math.ceil(n_batches / p) * t_batch * (1.0 + spread)
        rounds = self.rounds * t_allreduce(p, 24.0 * p, a, b, g)
        final = (t_fold_today if fold == 'today' else t_fold_tree)(p, self.s, a, b, g)
        final += t_reduce_small(p, 24.0 * n_batches + 100.0, a, b, g)
        bcast = t_bcast(p, self.s_in, a, b)
        total = self.t_setup + bcast + compute + rounds + final
        return dict(total=total, setup=self.t_setup, bcast=bcast, compute=compute,
                    rounds=rounds, final=final, w=self.n * self.c_ph)


def efficiency_table(recs, alpha, here, gamma, c_tally):
    """The 1 -> 2 rank table: wall-time ratios per repetition, the control's, the model's."""
    eff = median_of(recs, part='efficiency')
    if eff:
        print('\n## 1 -> 2 ranks (median over repetitions)')
        print('| workload | 1 rank wall s | 2 ranks wall s | ratio | control ratio | model ratio | '
              'CPU s 1 rank / 2 ranks / control | load |')
        print('|---|---|---|---|---|---|---|---|')
        for case in sorted({r['case'] for r in eff}):
            by = {k: [r for r in eff if r['case'] == case and r['kind'] == k]
                  for k in ('np1', 'np2', 'halves')}
            if not all(by.values()):
                continue
            def key(r):
                return r['file'], r['rep']
            reps = sorted({key(r) for r in by['np1']} & {key(r) for r in by['np2']}
                          & {key(r) for r in by['halves']})
            w1 = {key(r): r['wall_time_s'] for r in by['np1']}
            w2 = {key(r): r['wall_time_s'] for r in by['np2']}
            wh = {key(r): r['wall_time_s'] for r in by['halves']}
            ratio = st.median([w2[k] / w1[k] for k in reps])
            control = st.median([wh[k] / w1[k] for k in reps])
            r1 = by['np1'][0]
            setup = st.median([r['setup_time_s'] for r in by['np1']])
            c_ph = st.median([r['cpu_time_s'] / r['n_photons'] for r in by['np1']])
            s_tally = TALLY.get(case, 1)
            wl = Workload(case, r1['n_photons'], c_ph, s_tally, INPUT_BYTES.get(case, 0), setup, 0,
                          batch=r1['photons_per_batch'])
            m1 = wl.time(1, alpha, here, gamma, c_tally)['total']
            m2 = wl.time(2, alpha, here, gamma, c_tally)['total']
            cpu = [st.median([r['cpu_time_s'] for r in by[k]]) for k in ('np1', 'np2', 'halves')]
            loads = [r[k] for v in by.values() for r in v for k in ('load_before', 'load_after')]
            print(f'| {case} | {st.median(w1.values()):.2f} | {st.median(w2.values()):.2f} | '
                  f'{ratio:.3f} | {control:.3f} | {m2 / m1:.3f} | {cpu[0]:.2f} / {cpu[1]:.2f} / '
                  f'{cpu[2]:.2f} | {min(loads):.1f} .. {max(loads):.1f} |')



def checkpoint_table(recs):
    """The time of one checkpoint measured here (part checkpoint of run_scaling.py): the wall
    time with checkpoints minus that without, over the 3 checkpoints of a run, per kumo."""
    ck = [r for r in recs if r['part'] == 'checkpoint']
    if not ck:
        return
    print('\n## One checkpoint measured here (median over pairs of runs; oversubscribed, one disk)')
    print('| kumo | ranks | slot MB | s per checkpoint (wall difference / 3) | reported by kumo s | '
          'bytes through rank 0 (after: at most) | pairs |')
    print('|---|---|---|---|---|---|---|')
    for kumo in sorted({r['kumo'] for r in ck}):
        for p in sorted({r['ranks'] for r in ck}):
            on = [r for r in ck if r['kumo'] == kumo and r['ranks'] == p and r['interval'] > 0]
            off = [r for r in ck if r['kumo'] == kumo and r['ranks'] == p and r['interval'] == 0]
            pairs = list(zip(sorted(on, key=lambda r: r['time']), sorted(off, key=lambda r: r['time'])))
            if not pairs:
                continue
            d = [(x['wall_time_s'] - y['wall_time_s']) / 3.0 for x, y in pairs]
            reported = [t for r in on for t in r['reported_checkpoint_s']]
            m = 16.0 * on[0]['tally_doubles'] + SLOT_EXTRA
            n_done = 4 * p   # at most: the per-batch records (24 B each) and the CPU time
            through = (p - 1) * m if not reported else 24.0 * n_done + 8.0
            rep = f'{st.median(reported):.3f}' if reported else '-'
            print(f'| {kumo} | {p} | {m / 1e6:.1f} | {st.median(d):.3f} '
                  f'({min(d):.3f} .. {max(d):.3f}) | {rep} | {through:.3g} | {len(d)} |')


def checkpoint_model(alpha_beta):
    """One checkpoint of the tiled LES (9.4e6 voxels) and of the LES at P ranks."""
    na, nb = alpha_beta
    for fs_name, fs in FS_ASSUMED.items():
        print(f'\nOne checkpoint [s], {fs_name} (node {fs[1] / 1e9:.0f} GB/s, {fs[2]:.0f} '
              f'metadata operations/s, {fs[3]} ranks per node): rank 0 alone / per-rank parts')
        print('| tally | ' + ' | '.join(f'P={p}' for p in P_LIST) + ' |')
        print('|---|' + '---|' * len(P_LIST))
        for name, s in (('LES (S 3.0e5)', TALLY['les_flux']), ('tiled LES (S 1.3e7)', LARGE_TALLY)):
            row = [f'{t_ckpt_rank0(p, s, na, nb, fs):.3g} / {t_ckpt_parts(p, s, na, nb, fs):.3g}'
                   for p in P_LIST]
            print(f'| {name} | ' + ' | '.join(row) + ' |')


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('results', nargs='+')
    a = ap.parse_args()
    recs = load(a.results)
    checkpoint_table(recs)
    if not collective(recs, 'pingpong', 2) and not any(r['part'] == 'efficiency' for r in recs):
        checkpoint_model((NETWORKS['HDR'][0], beta_of(NETWORKS['HDR'][1])))
        return

    if not collective(recs, 'pingpong', 2):
        # efficiency runs alone: the 1 -> 2 rank table, with the collectives taken as free
        recs = [r for r in recs if r['part'] == 'efficiency']
        print('(no collective timings in these files: the model ratio neglects them)')
        efficiency_table(recs, 0.0, beta_of(0.0), 0.0, 0.0)
        return
    alpha, beta_c, beta_m = local_network(recs)
    gamma = gamma_from_fold(recs, alpha, beta_m)
    here = beta_of(beta_c, beta_m)
    print('## Network parameters')
    print(f'here (shared memory, 2 ranks): alpha {alpha * 1e6:.2f} us, beta {beta_c * 1e9:.3f} '
          f'ns/B in cache (64 KiB - 4 MiB, {1 / beta_c / 1e9:.1f} GB/s), {beta_m * 1e9:.3f} ns/B '
          f'from memory (>= 16 MiB, {1 / beta_m / 1e9:.2f} GB/s); gamma {gamma * 1e9:.3f} ns/B')
    for k, (na, nb) in NETWORKS.items():
        print(f'{k}: alpha {na * 1e6:.1f} us, beta {nb * 1e9:.3f} ns/B ({1 / nb / 1e9:.0f} GB/s)')

    # measured collectives against the model with the local parameters
    print('\n## Collectives measured here against the model (here parameters)')
    print('| operation | ranks | MB | measured ms | model ms |')
    print('|---|---|---|---|---|')
    for ranks in (2, 4, 8):
        for op in ('bcast', 'fold', 'tree', 'reduce'):
            for m, t in sorted(collective(recs, op, ranks).items()):
                if m < 1e6:
                    continue
                if op == 'bcast':
                    mod = t_bcast(ranks, m, alpha, here)
                elif op == 'fold':
                    mod = t_fold_today(ranks, m / 16.0, alpha, here, gamma)
                else:   # the tree, and MPI_Reduce modelled as a tree
                    mod = t_fold_tree(ranks, m / 16.0, alpha, here, gamma)
                over = ' (oversubscribed)' if ranks > 2 else ''
                print(f'| {op} | {ranks}{over} | {m / 1e6:.1f} | {t * 1e3:.2f} | {mod * 1e3:.2f} |')

    # per-tally-double cost of a batch (clear + add to the sums), from the large scene
    large = median_of(recs, part='large')
    c_tally = None
    if large:
        one = [r for r in large if r['ranks'] == 1]
        two = [r for r in large if r['ranks'] == 2]
        s = one[0]['tally_doubles']
        after1 = st.median([r['wall_time_s'] - r['setup_time_s'] for r in one])
        after2 = st.median([r['wall_time_s'] - r['setup_time_s'] for r in two])
        # kumo's CPU time covers the batch loop: two batches of a negligible 1000 photons each,
        # i.e. twice clearing the tally and adding it to the sums (wall times here include
        # waiting for a core when the machine is loaded)
        c_tally = st.median([r['cpu_time_s'] for r in one]) / (2.0 * s)
        print('\n## The large scene (768 x 768 x 16 voxels, tally '
              f'{s:.3g} doubles per sum), 2 batches of 1000 photons')
        print(f'set-up: 1 rank {st.median([r["setup_time_s"] for r in one]):.2f} s, 2 ranks '
              f'{st.median([r["setup_time_s"] for r in two]):.2f} s; after set-up: 1 rank '
              f'{after1:.2f} s, 2 ranks {after2:.2f} s (one batch per rank plus the fold of '
              f'{16 * s / 1e6:.0f} MB: model {t_fold_today(2, s, alpha, here, gamma):.2f} s)')
        print(f'c_tally = {c_tally * 1e9:.2f} ns per tally double per batch')
        t_setup_large = st.median([r['setup_time_s'] for r in one])
    if c_tally is None:
        c_tally = 1.0e-9
        t_setup_large = None

    efficiency_table(recs, alpha, here, gamma, c_tally)

    # workloads for the model
    wk = median_of(recs, case='les_flux', kind='work')
    if wk:
        c_ph = st.median([r['cpu_time_s'] / r['n_photons'] for r in wk])
        rel_r = st.median([r['reflectance_stderr'] / r['reflectance'] * math.sqrt(r['n_photons'])
                           for r in wk])
        rel_v = st.median([r['voxel_median_rel_stderr'] * math.sqrt(r['n_photons']) for r in wk])
        setup = st.median([r['setup_time_s'] for r in wk])
        n_flux = (rel_r / 1.0e-3) ** 2
        n_heat = (rel_v / 0.10) ** 2
        print(f'\n## Workloads (LES without radiances, serial): {c_ph * 1e6:.2f} us per photon; '
              f'photons to 0.1 % on R: {n_flux:.3g} (W {n_flux * c_ph:.1f} s); to 10 % on the '
              f'median cloudy voxel: {n_heat:.3g} (W {n_heat * c_ph:.1f} s); set-up {setup:.2f} s')
        les = TALLY['les_flux'], INPUT_BYTES['les_flux'], setup
        loads = [
            Workload('LES flux to 0.1 %', n_flux, c_ph, *les, rounds=10),
            Workload('LES heating to 10 %', n_heat, c_ph, *les, rounds=1),
            Workload('LES heating to 1 %', 100 * n_heat, c_ph, *les, rounds=1),
        ]
        if t_setup_large is not None:
            # the same photons per column on 144 times the columns
            big = LARGE_TALLY, LARGE_INPUT, t_setup_large
            loads.append(Workload('tiled LES (9.4e6 voxels) heating to 10 %', 144 * n_heat, c_ph,
                                  *big, rounds=1))
            loads.append(Workload('tiled LES (9.4e6 voxels) heating to 1 %', 14400 * n_heat, c_ph,
                                  *big, rounds=1))
        for net in ('HDR', 'slow'):
            na, nb = NETWORKS[net][0], beta_of(NETWORKS[net][1])
            print(f'\n### Model, {net} network')
            print('| workload | fold | ' + ' | '.join(f'P={p}' for p in P_LIST) + ' |')
            print('|---|---|' + '---|' * len(P_LIST))
            for wl in loads:
                for fold in ('today', 'tree'):
                    row = []
                    for p in P_LIST:
                        t = wl.time(p, na, nb, gamma, c_tally, fold=fold)
                        row.append(f'{t["w"] / (p * t["total"]):.2f}')
                    print(f'| {wl.name} | {fold} | ' + ' | '.join(row) + ' |')
            print('\nParts of T(P) at P = 1000 [s] (today / tree):')
            for wl in loads:
                t = wl.time(1000, na, nb, gamma, c_tally)
                u = wl.time(1000, na, nb, gamma, c_tally, fold='tree')
                v = wl.time(1000, na, nb, gamma / 10.0, c_tally)
                print(f'  {wl.name}: W/P {t["w"] / 1000:.3g}, set-up {t["setup"]:.3g}, bcast '
                      f'{t["bcast"]:.3g}, batches {t["compute"]:.3g}, rounds {t["rounds"]:.3g}, '
                      f'final {t["final"]:.3g} / {u["final"]:.3g} (today with gamma / 10: '
                      f'{v["final"]:.3g}); total {t["total"]:.3g} / {u["total"]:.3g}')
            checkpoint_model((na, nb))


#: Tally doubles per sum: 64 x 64 columns, flux maps at the 19 levels (3 per level), 16 voxel
#: layers, radiance maps of one direction (les), a few dozen domain values.
TALLY = {'les': 4096 * (3 * 19 + 16 + 1) + 100, 'les_flux': 4096 * (3 * 19 + 16) + 100,
         'hg_slab': 50}
#: Input bytes broadcast: the scene file's fields (extinction, albedo as doubles, phase index).
INPUT_BYTES = {'les': 65536 * 20, 'les_flux': 65536 * 20, 'hg_slab': 0}
LARGE_TALLY = 768 * 768 * (6 + 16)
LARGE_INPUT = 768 * 768 * 16 * 20

if __name__ == '__main__':
    main()
