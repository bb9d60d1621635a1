"""Fold-free grids (:mod:`clothgrid.foldfree`, ``generate(functional=...)``, ``--functional``/``--strict``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import clothgrid
from clothgrid import Boundary, InputError, generate, quality
from clothgrid.cli import main
from clothgrid.foldfree import corner_jacobians, untangle
from clothgrid.grid import Grid
from conftest import regions_with_corners, smooth_quad_sides

REGIONS = regions_with_corners()
TIE = Path(__file__).parent / "data" / "regions" / "roache-tie.json"
SHARED = Path(__file__).resolve().parents[2] / "shared" / "patterns"


def _folded(points: np.ndarray, dim: int) -> int:
    """Folded cells of a relaxed grid (clothgrid.quality)."""
    return quality(Grid.from_points(points, info={}, dim=dim)).folded


def test_the_eight_roache_regions_are_there():
    assert sorted(p.stem for p in REGIONS) == [
        "roache-" + n for n in ("annulus", "dome", "horn", "nhorseshoe", "plow", "shell", "swan", "tie")]


@pytest.mark.parametrize("weights", ["paper", "uniform"])
@pytest.mark.parametrize("nodes", [None, 80], ids=["native20", "80x80"])
@pytest.mark.parametrize("path", REGIONS, ids=lambda p: p.stem)
def test_auto_is_fold_free_on_roache_regions(path, nodes, weights):
    b = clothgrid.load_boundary(path)
    grid = generate(b, nodes, weights=weights, functional="auto")
    q = quality(grid)
    assert q.folded == 0
    assert grid.info["folded"] == 0
    length = generate(b, nodes, weights=weights)
    assert grid.info["folded_before"] == quality(length).folded
    assert grid.info["functional"] in (("foldfree",) if grid.info["folded_before"] else
                                       ("length", "evened", "foldfree"))
    # Boundary nodes are kept exactly.
    for sl in (np.s_[0], np.s_[-1], np.s_[:, 0], np.s_[:, -1]):
        assert np.array_equal(grid.points[sl], length.points[sl])


def test_auto_returns_the_length_grid_when_it_does_not_fold(rng):
    unchanged = 0
    for _ in range(12):
        b = Boundary.from_sides(*smooth_quad_sides(rng, 17, 17, amp=0.03))
        length = generate(b, weights="uniform")
        if quality(length).folded:
            continue
        grid = generate(b, weights="uniform", functional="auto")
        assert grid.info["folded_before"] == 0 == grid.info["folded"]
        if grid.info["evened"]["moved"] == 0:        # nothing poor, no outlying edge: as it was
            assert np.array_equal(grid.points, length.points) and grid.info["functional"] == "length"
            unchanged += 1
        else:
            assert grid.info["functional"] == "evened"
    assert unchanged >= 3


def test_auto_evens_outlying_edges_without_folding_or_sharper_angles():
    """roache-shell does not fold, but its length grid has a few edges far from the rest: auto
    moves the nodes near them, lowering the edge spread, keeping the boundary and every angle
    that was at least 25 degrees at least 25 degrees."""
    from clothgrid.quality import sim_figures

    shell = clothgrid.load_boundary(REGIONS[[p.stem for p in REGIONS].index("roache-shell")])
    length = generate(shell, weights="uniform")
    assert quality(length).folded == 0
    grid = generate(shell, weights="uniform", functional="auto")
    before, after = sim_figures(length.points), sim_figures(grid.points)
    assert grid.info["functional"] == "evened" and quality(grid).folded == 0
    assert after["edge_spread"] < 0.8 * before["edge_spread"]
    assert grid.info["evened"]["spread_after"] == pytest.approx(after["edge_spread"])
    assert after["min_angle_deg"] >= min(before["min_angle_deg"], 25.0) - 1e-9
    for sl in (np.s_[0], np.s_[-1], np.s_[:, 0], np.s_[:, -1]):
        assert np.array_equal(grid.points[sl], length.points[sl])


def test_foldfree_always_runs_and_keeps_a_clockwise_or_3d_planar_piece_unfolded(rng):
    data = json.loads(TIE.read_text())
    pts = np.asarray(data["outline"], dtype=float)
    b = Boundary.from_outline(pts, data["corners"])
    g = generate(b, functional="foldfree")
    assert g.info["functional"] == "foldfree" and quality(g).folded == 0 < g.info["folded_before"]
    # The same piece tilted into a plane in 3D.
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    b3 = Boundary.from_sides(*[np.column_stack([s, np.zeros(len(s))]) @ rot.T
                                for s in (b.bottom[:, :2], b.right[:, :2], b.top[:, :2], b.left[:, :2])])
    g3 = generate(b3, functional="auto")
    assert g3.info["functional"] == "foldfree" and quality(g3).folded == 0
    # Mirrored (clockwise) piece.
    bm = Boundary.from_sides(*[s[:, :2] * [-1.0, 1.0] for s in (b.bottom, b.right, b.top, b.left)])
    gm = generate(bm, functional="auto")
    assert quality(gm).folded == 0


def test_untangle_api():
    b = clothgrid.load_boundary(TIE)
    g = generate(b)
    points, info = untangle(g.points, dim=2)
    assert info["untangled"] and info["min_corner_jacobian"] > 0
    assert (corner_jacobians(points[..., :2]) > 0).all()
    assert np.array_equal(points[0], g.points[0]) and np.array_equal(points[:, -1], g.points[:, -1])
    with pytest.raises(InputError):
        untangle(g.points[..., :2])
    with pytest.raises(InputError):
        untangle(g.points, max_iter=0)


def test_bad_functional_and_curved_piece(rng):
    b = clothgrid.load_boundary(TIE)
    with pytest.raises(InputError, match="functional"):
        generate(b, functional="area")
    curved = Boundary.from_sides(*smooth_quad_sides(rng, 12, 12, dim=3))
    with pytest.raises(InputError, match="planar"):
        generate(curved, functional="foldfree")
    grid = generate(curved, functional="auto")          # curved: never untangled
    assert grid.info["functional"] == "length"


def test_cli_strict_and_auto(tmp_path, capsys):
    out = tmp_path / "tie.npz"
    length = ["--functional", "length", "--weights", "paper"]      # the paper's method folds the tie
    assert main(["generate", str(TIE), "-o", str(out), "-q", "--strict", *length]) == 3
    assert not out.exists()
    err = capsys.readouterr().err
    assert "10 folded cells" in err and "(0, 0)" in err
    assert main(["generate", str(TIE), "-o", str(out), "-q", "--weights", "paper", "--strict"]) == 0  # auto: default
    assert out.exists()
    captured = capsys.readouterr()
    assert "length functional:" in captured.out and captured.out.count("folded cells:") == 2
    assert "folded cells: 0" in captured.out.split("fold-free")[1]
    out.unlink()
    assert main(["generate", str(TIE), "-o", str(out), "-q", *length]) == 0           # warns, writes
    err = capsys.readouterr().err
    assert "warning: 10 folded cells (first at cells (0, 0)" in err and "--functional auto" in err
    assert main(["generate", str(TIE), "-o", str(tmp_path / "x.npz"), "--functional", "bad"]) == 2
    assert not (tmp_path / "x.npz").exists()


def test_a_wild_outline_gets_no_more_folds_and_the_untangling_stops_when_it_stalls(tmp_path):
    """Found by tests/test_fuzz.py: a GarmentCode waistband with one vertex moved 77 m away (its
    circle arcs then swing round a far-off chord) ran 60 untangling rounds of every node (minutes
    at 10 cm) and handed back 16 times the length grid's folded cells. Now every-node untangling
    stops after ``RELAX_STALL`` rounds without fewer folded corners, and a fold-free grid with more
    folded cells than the length grid is not kept."""
    from clothgrid.foldfree import RELAX_ROUNDS, RELAX_STALL
    from clothgrid.pipeline import generate_piece
    from clothgrid.readers import read_pieces

    spec = json.loads((Path(__file__).parent / "data" / "garmentcode" / "flare_skirt_specification.json")
                      .read_text())
    spec["pattern"]["panels"]["wb_front"]["vertices"][3] = [-7683, 0]
    src = tmp_path / "spec.json"
    src.write_text(json.dumps(spec))
    piece = next(p for p in read_pieces(src) if p.name == "wb_front")
    grid = generate_piece(piece, edge_length="60cm")
    info = grid.info
    assert info["folded_before"] > 0
    assert info["folded"] == info["folded_before"] == quality(grid).folded
    assert "foldfree_rejected" in info and info["functional"] == "length"
    # 8 rounds on the poor cells' nodes, then every node (first on the coarser grids, which stop on
    # the strict stall rule) until it stalls: all the grids' rounds together under the every-node
    # cap of the finest alone (28 when measured; 46 before the finest took the strict rule too)
    assert info["foldfree"]["levels"] >= 2
    assert info["foldfree"]["rounds"] < 2 * RELAX_ROUNDS, info["foldfree"]
    assert RELAX_STALL < 10


def test_the_margin_cap_keeps_the_quality_of_the_wide_margin(monkeypatch):
    """At 512^2 an eighth of the shorter side is 64 lines; capped at ``MAX_MARGIN`` (8) the relax
    moves under a third of the nodes of the uncapped margin and leaves a grid as good where it
    counts: no fold, a smallest scaled Jacobian and corner Jacobian no smaller. The wide smoothing
    lifts more cells' smallest corner over 30 degrees (and stretches edges: spread 15.1 against
    12.6), so the narrow margin may leave up to 30 % more cells under it (380 against 308 when
    measured; under 20 degrees, 6 against 4)."""
    import clothgrid.foldfree as ff
    from clothgrid.foldfree_kernels import cell_min_sine

    b = clothgrid.load_boundary(Path(clothgrid.__file__).parent / "data" / "tshirt_front.json")
    length = generate(b, (512, 512), weights="uniform", functional="length")
    assert quality(length).folded > 0
    got = {}
    for cap in (ff.MAX_MARGIN, 10**9):
        monkeypatch.setattr(ff, "MAX_MARGIN", cap)
        pts, info = ff.relax(length.points, dim=length.dim)
        q = quality(Grid.from_points(pts, info={}, dim=length.dim))
        sines = cell_min_sine(np.ascontiguousarray(pts[..., :2]))
        got[cap] = (info["moved"], q.folded, q.min_scaled_jacobian, info["min_corner_jacobian"],
                    int((sines < 0.5).sum()))
    (moved, folded, sj, cj, poor), (moved_w, folded_w, sj_w, cj_w, poor_w) = got[8], got[10**9]
    assert folded == folded_w == 0
    assert moved < moved_w / 3
    assert sj >= sj_w - 1e-3 and cj >= cj_w - 1e-3
    assert poor <= 1.3 * poor_w + 5


def test_folds_the_narrow_margin_leaves_are_untangled_on_the_wide_one(monkeypatch):
    """Where the rounds on the narrow margin leave folds, they run again on up to ``WIDE_MARGIN``
    lines before every node is untangled: on the tie at 80 x 80 with no margin at all (the folded
    and poor cells' own nodes) folds remain, and the wide margin (10 lines) untangles it, moving
    a fifth of the interior nodes."""
    import clothgrid.foldfree as ff

    monkeypatch.setattr(ff, "MAX_MARGIN", 0)
    length = generate(clothgrid.load_boundary(TIE), 80, weights="paper")
    said = []
    pts, info = ff.relax(length.points, dim=length.dim, margin=0, progress=said.append)
    assert len(said) == 2 and "within 0 lines" in said[0] and not said[0].endswith(" 0 folded corners left")
    assert "within 10 lines" in said[1] and said[1].endswith(" 0 folded corners left")
    assert info["untangled"] and _folded(pts, length.dim) == 0
    assert 0 < info["moved"] < 78 * 78 / 4


def test_the_coloured_parallel_sweeps_match_the_ordered_ones(monkeypatch):
    """Large active sets are swept in four colours, each colour in parallel: at 512^2 (11,482 nodes)
    the relaxed grid is as good as the ordered sweeps' (no fold, the smallest scaled Jacobian and
    the count of cells with a corner under 30 degrees within a few per cent), and every node that
    moved is an active one. Both take the plain step here (the ordered sweeps' ``OVERRELAX`` is
    another step rule, not another order)."""
    import clothgrid.foldfree as ff
    from clothgrid.foldfree_kernels import cell_min_sine

    monkeypatch.setattr(ff, "OVERRELAX", 1.0)
    b = clothgrid.load_boundary(Path(clothgrid.__file__).parent / "data" / "tshirt_front.json")
    length = generate(b, (512, 512), weights="uniform", functional="length")
    got = {}
    for threshold in (10**12, 0):
        monkeypatch.setattr(ff, "PARALLEL_NODES", threshold)
        pts, info = ff.relax(length.points, dim=length.dim)
        q = quality(Grid.from_points(pts, info={}, dim=length.dim))
        sines = cell_min_sine(np.ascontiguousarray(pts[..., :2]))
        got[threshold] = (pts, info["moved"], q.folded, q.min_scaled_jacobian, int((sines < 0.5).sum()))
    (p_ord, moved, folded, sj, poor), (p_col, moved_c, folded_c, sj_c, poor_c) = got[10**12], got[0]
    assert folded == folded_c == 0 and moved == moved_c
    assert sj_c == pytest.approx(sj, rel=0.05)
    assert abs(poor_c - poor) <= 0.05 * poor + 5
    assert not np.array_equal(p_ord, p_col)                 # another order, another (as good) grid
    shifted = np.linalg.norm(p_col - length.points, axis=-1) > 1e-9 * b.size    # beyond the frame's rounding
    assert 0 < np.count_nonzero(shifted) <= moved


def _two_parts(nodes):
    """Order and starts of ``nodes`` in two parts of whole components, alternating by size."""
    from clothgrid.foldfree_kernels import node_components

    label, count = node_components(nodes)
    part = (np.argsort(np.argsort(-np.bincount(label, minlength=count), kind="stable")) % 2)[label]
    order = np.argsort(part, kind="stable")
    return order, np.searchsorted(part[order], np.arange(3)).astype(np.int64)


def _quiet_reference(X, nodes, delta2, sweeps, tol, omega, quiet, colours=False):
    """sweep_nodes' sweeps with its skip rule, written out in Python over the kernel's node step:
    a node is stepped where it or one of its 8 neighbours moved more than ``quiet`` in this sweep or
    the last (every node in the first sweep); ``colours``: the nodes colour by colour
    (``2 (i mod 2) + (j mod 2)``), as sweep_nodes_coloured takes them. Returns what the kernels do."""
    import clothgrid.foldfree_kernels as fk

    w = fk.new_scratch(1)[0]
    stamp = {}
    if colours:
        nodes = nodes[np.argsort(2 * (nodes[:, 0] & 1) + (nodes[:, 1] & 1), kind="stable")]
    done, last, visits = 0, 0.0, 0
    for s in range(1, sweeps + 1):
        done += 1
        last = 0.0
        for i, j in nodes:
            if quiet > 0 and max(stamp.get((a, b), 0) for a in (i - 1, i, i + 1) for b in (j - 1, j, j + 1)) < s - 1:
                continue
            visits += 1
            mv = fk._relax_node(X, i, j, delta2, w, omega)
            if quiet > 0 and mv > quiet:
                stamp[i, j] = s
            last = max(last, mv)
        if last < tol:
            break
    return done, last, visits


@pytest.mark.parametrize("quiet", [0.0, 1e-3, 3e-2])
def test_relax_sweeps_pass_over_quiet_nodes_as_written(quiet):
    """The sweeps' skip rule (``quiet``: a node is stepped only where it or a neighbour moved more
    than ``quiet`` in this sweep or the last) against the rule written out in Python, on fresh
    folded blocks: the ordered sweeps, their parts on the threads and the coloured sweeps give the
    reference's grid bit for bit, its sweeps, last move and node steps; ``quiet = 0`` steps every
    node every sweep, and a ``quiet`` above zero passes some over."""
    import clothgrid.foldfree as ff
    import clothgrid.foldfree_kernels as fk

    rng = np.random.default_rng()
    nu, nv = 60, 70
    u, v = np.meshgrid(np.arange(nu, dtype=float), np.arange(nv, dtype=float), indexing="ij")
    X = np.stack([u, v], -1)
    mask = np.zeros((nu, nv), bool)
    for a, b in ((2, 2), (2, 37), (32, 2), (32, 37)):
        i, j = int(rng.integers(a, a + 14)), int(rng.integers(b, b + 19))
        mask[i:i + 12, j:j + 12] = True
        X[i + 3:i + 9, j + 3:j + 9] += rng.normal(scale=0.45, size=(6, 6, 2))
    nodes = np.argwhere(mask).astype(np.int64)
    delta2, tol = ff.DELTA_SMOOTH ** 2, 1e-3
    R = X.copy()
    want = _quiet_reference(R, nodes, delta2, 40, tol, ff.OVERRELAX, quiet)
    A = X.copy()
    got = fk.sweep_nodes(A, nodes, delta2, 40, tol, ff.OVERRELAX, quiet)
    assert got == want and np.array_equal(A, R) and not np.array_equal(A, X)
    if quiet == 0.0:
        assert got[2] == got[0] * len(nodes)
    else:
        assert got[2] < got[0] * len(nodes)
    order, starts = _two_parts(nodes)
    B = X.copy()
    assert fk.sweep_nodes_parts(B, np.ascontiguousarray(nodes[order]), starts, delta2, 40, tol, ff.OVERRELAX,
                                quiet) == want and np.array_equal(B, R)
    # the coloured sweeps (the plain step) against the reference taken colour by colour
    R = X.copy()
    want = _quiet_reference(R, nodes, delta2, 40, tol, 1.0, quiet, colours=True)
    colour = 2 * (nodes[:, 0] & 1) + (nodes[:, 1] & 1)
    order = np.argsort(colour, kind="stable")
    starts = np.searchsorted(colour[order], np.arange(5)).astype(np.int64)
    C = X.copy()
    got = fk.sweep_nodes_coloured(C, np.ascontiguousarray(nodes[order]), starts, delta2, 40, tol, 1.0, quiet)
    assert got == want and np.array_equal(C, R)


def test_node_components_join_the_eight_neighbours():
    """node_components against SciPy's labelling with the 3 x 3 structure, on fresh random node sets
    (the same partition; labels numbered by first node)."""
    from scipy import ndimage

    from clothgrid.foldfree_kernels import node_components

    rng = np.random.default_rng()
    for _ in range(30):
        nu, nv = (int(k) for k in rng.integers(3, 40, 2))
        mask = rng.random((nu, nv)) < rng.uniform(0.05, 0.5)
        nodes = np.argwhere(mask).astype(np.int64)
        label, count = node_components(nodes)
        ref, n_ref = ndimage.label(mask, structure=np.ones((3, 3)))
        assert count == n_ref
        ref_of = ref[nodes[:, 0], nodes[:, 1]]
        if len(nodes):
            assert label[0] == 0 and np.all(np.diff(np.maximum.accumulate(label)) <= 1)
        for a in range(count):       # one to one
            assert len(np.unique(ref_of[label == a])) == 1


def test_relax_sweeps_in_parts_give_the_ordered_sweeps_bits():
    """sweep_nodes_parts (whole components of the active set on the threads) leaves the grid, the
    sweep count and the last move of sweep_nodes bit for bit, on a grid with several poor
    regions; node_parts deals whole components to the parts and keeps each in list order."""
    import numba

    import clothgrid.foldfree as ff
    from clothgrid.foldfree_kernels import node_components, sweep_nodes, sweep_nodes_parts

    rng = np.random.default_rng()
    nu, nv = 60, 70
    u, v = np.meshgrid(np.arange(nu, dtype=float), np.arange(nv, dtype=float), indexing="ij")
    X = np.stack([u, v], -1)
    # four 12 x 12 blocks, one in each quarter of the grid (apart: four components), folded inside
    blocks = [(int(rng.integers(a, a + 14)), int(rng.integers(b, b + 19))) for a in (2, 32) for b in (2, 37)]
    mask = np.zeros((nu, nv), bool)
    for i, j in blocks:
        mask[i:i + 12, j:j + 12] = True
        X[i + 3:i + 9, j + 3:j + 9] += rng.normal(scale=0.45, size=(6, 6, 2))    # folds
    nodes = np.argwhere(mask).astype(np.int64)
    order, starts = _two_parts(nodes)
    assert starts[1] > 0 and starts[2] > starts[1]
    A, B = X.copy(), X.copy()
    got_a = sweep_nodes(A, nodes, ff.DELTA_SMOOTH ** 2, 40, 1e-3, ff.OVERRELAX)
    got_b = sweep_nodes_parts(B, np.ascontiguousarray(nodes[order]), starts, ff.DELTA_SMOOTH ** 2, 40, 1e-3,
                              ff.OVERRELAX)
    assert got_a == got_b and np.array_equal(A, B) and not np.array_equal(A, X)
    # node_parts: whole components, each part in list order
    parts = ff.node_parts(nodes)
    if numba.get_num_threads() >= 2:
        order, starts = parts
        assert sorted(order) == list(range(len(nodes)))
        label = node_components(nodes)[0]
        for p in range(len(starts) - 1):
            assert np.all(np.diff(order[starts[p]:starts[p + 1]]) > 0)
            others = np.setdiff1d(np.arange(len(nodes)), order[starts[p]:starts[p + 1]])
            assert not np.intersect1d(label[order[starts[p]:starts[p + 1]]], label[others]).size
    else:
        assert parts is None


def test_corner_measures_of_large_grids_run_in_parallel_with_the_same_results(rng, monkeypatch):
    """corner_min and cell_min_sine take rows of cells in parallel from PARALLEL_CELLS cells on:
    on fresh grids with folded and degenerate cells both forms give the same numbers, bit for bit,
    and the fold count of the definition (corner_jacobians)."""
    import clothgrid.foldfree_kernels as fk

    for _ in range(3):
        nu, nv = rng.integers(3, 50, size=2)
        i, j = np.meshgrid(np.arange(nu, dtype=float), np.arange(nv, dtype=float), indexing="ij")
        X = np.stack([i, j], axis=-1) + rng.uniform(-0.6, 0.6, size=(nu, nv, 2))
        X[1, 1] = X[1, 2]                               # a zero-length edge
        X = np.ascontiguousarray(X)
        out = {}
        for cells in (10**12, 0):                       # serial, then parallel
            monkeypatch.setattr(fk, "PARALLEL_CELLS", cells)
            out[cells] = fk.corner_min(X, False), fk.cell_min_sine(X)
        (jmin_s, bad_s), sine_s = out[10**12]
        (jmin_p, bad_p), sine_p = out[0]
        assert jmin_s == jmin_p and bad_s == bad_p and np.array_equal(sine_s, sine_p)
        assert bad_s == int((corner_jacobians(X) <= 0).sum()) > 0
        assert np.array_equal(sine_s, _cell_min_sine_numpy(X))


def _cell_min_sine_numpy(X: np.ndarray) -> np.ndarray:
    """Each cell's smallest corner sine, corner by corner in NumPy: at corner ``k`` (quad order
    (i, j), (i+1, j), (i+1, j+1), (i, j+1)) the edges to corners ``k+1`` and ``k-1``,
    ``a x b / (|a| |b|)``, -1 where an edge has zero length."""
    c = [X[:-1, :-1], X[1:, :-1], X[1:, 1:], X[:-1, 1:]]
    best = np.full(c[0].shape[:2], np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for k in range(4):
            a, b = c[(k + 1) % 4] - c[k], c[(k + 3) % 4] - c[k]
            la = np.sqrt(a[..., 0] * a[..., 0] + a[..., 1] * a[..., 1])
            lb = np.sqrt(b[..., 0] * b[..., 0] + b[..., 1] * b[..., 1])
            v = np.where((la == 0) | (lb == 0), -1.0, (a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]) / (la * lb))
            best = np.minimum(best, v)
    return best


def test_node_energy_lanes_match_one_triangle_at_a_time():
    """The vectorised node energy (twelve triangles in the lanes of a scratch row) gives the bits of
    _tri called triangle by triangle and summed in the documented order, on fresh random nodes
    (folded ones too: then both are inf)."""
    from clothgrid import foldfree_kernels as K

    rng = np.random.default_rng()
    w = K.new_scratch(1)[0]
    for trial in range(300):
        X = np.stack(np.meshgrid(np.arange(3.0), np.arange(3.0), indexing="ij"), axis=-1)
        X += rng.normal(scale=0.6 if trial % 3 else 0.15, size=X.shape)
        px, py = X[1, 1] + rng.normal(scale=0.3, size=2)
        d4 = float(rng.choice([0.0, 1e-6, 1e-2]))
        # cells (i-1, j-1), (i, j-1), (i-1, j), (i, j) around the node: (n, o, q) of each
        n_o_q = (((0, 1), (0, 0), (1, 0)), ((1, 0), (2, 0), (2, 1)),
                 ((1, 2), (0, 2), (0, 1)), ((2, 1), (2, 2), (1, 2)))
        want = bool(trial % 2)
        total = np.zeros(6)
        folded = False
        for n, o, q in n_o_q:
            pts = {"p": (px, py), "n": tuple(X[n]), "o": tuple(X[o]), "q": tuple(X[q])}
            for apex, a_end, b_end, kind in (("q", "p", "o", 1), ("p", "n", "q", 0), ("n", "o", "p", 2)):
                got = K._tri(*pts[apex], *pts[a_end], *pts[b_end], d4, kind, want)
                if got[0] == np.inf:
                    folded = True
                total += np.array(got)          # the same order of additions as the kernel
        E = K._node_energy(X, 1, 1, px, py, d4, want, w)
        if folded:
            assert E[0] == np.inf
        else:
            assert np.array_equal(np.array(E), total), (trial, E, total)


@pytest.mark.parametrize("clockwise", [False, True])
def test_plane_coordinates_of_an_xy_piece_without_the_matrix_product(clockwise):
    """to_plane and _with_interior take the swap-and-negate frame of a piece in the xy-plane
    without a matrix product: the values of (R - centre) @ basis.T and centre + X @ basis (exact:
    +-1 times a coordinate plus zeros), and a 3D frame still goes through the product."""
    from clothgrid.foldfree import _with_interior, plane_frame, to_plane

    rng = np.random.default_rng()
    nu, nv = 7, 9
    u, v = np.meshgrid(np.linspace(0, 3, nu), np.linspace(0, 2, nv), indexing="ij")
    R = np.stack([u, v, np.zeros_like(u)], -1)
    R[1:-1, 1:-1, :2] += rng.normal(scale=0.05, size=(nu - 2, nv - 2, 2))
    R[2, 3, 0] = 0.0                                      # an exact zero coordinate, too
    if clockwise:
        R = R[::-1].copy()
    centre, basis = plane_frame(R, 2)
    X = to_plane(R, centre, basis)
    assert np.array_equal(X, (R - centre) @ basis.T)
    Y = X + rng.normal(scale=0.01, size=X.shape)
    want = R.copy()
    want[1:-1, 1:-1] = centre + Y[1:-1, 1:-1] @ basis
    want[1:-1, 1:-1, 2] = 0.0
    mine = R.copy()
    got = _with_interior(mine, Y, centre, basis, 2, copy=False)
    assert got is mine and np.array_equal(got, want)
    assert np.array_equal(_with_interior(R, Y, centre, basis, 2), want)
    # a tilted plane: the general frame, the product
    tilt = np.array([[1.0, 0, 0], [0, 0.6, 0.8], [0, -0.8, 0.6]])
    R3 = R @ tilt.T + [1.0, 2.0, 3.0]
    c3, b3 = plane_frame(R3, 3)
    assert np.array_equal(to_plane(R3, c3, b3), (R3 - c3) @ b3.T)


@pytest.mark.parametrize("clockwise", [False, True])
def test_shift_and_scale_in_the_plane_pass_give_numpys_bits(clockwise):
    """to_plane with a shift and scale (one kernel pass for an xy-piece) gives the bits of NumPy's
    multiply, subtract and divide one after the other, and _with_interior's way back those of
    multiply, add and the sign; the boundary nodes are kept as they were."""
    from clothgrid.foldfree import _with_interior, plane_frame, to_plane

    rng = np.random.default_rng()
    nu, nv = int(rng.integers(3, 40)), int(rng.integers(3, 40))
    R = np.zeros((nu, nv, 3))
    R[..., :2] = rng.normal(scale=rng.uniform(0.01, 100), size=(nu, nv, 2)) + rng.normal(size=2) * 50
    R[1, 1, 0] = -0.0
    if clockwise:
        R = R[::-1].copy()
    centre, basis = plane_frame(R, 2)
    shift, scale = rng.normal(size=2) * 3, float(rng.uniform(0.1, 10))
    ref = (R - centre) @ basis.T
    ref -= shift
    ref /= scale
    X = to_plane(R, centre, basis, shift, scale)
    assert np.array_equal(X.view(np.uint64), ref.view(np.uint64))
    Y = X + rng.normal(scale=0.01, size=X.shape)
    back = Y.copy()
    back *= scale
    back += shift
    want = R.copy()
    want[1:-1, 1:-1] = centre + back[1:-1, 1:-1] @ basis
    want[1:-1, 1:-1, 2] = 0.0
    got = _with_interior(R, Y.copy(), centre, basis, 2, shift=shift, scale=scale)
    assert np.array_equal(got[..., :2], want[..., :2]) and np.array_equal(got[..., 2], want[..., 2])
    assert np.array_equal(got[0], R[0]) and np.array_equal(got[:, -1], R[:, -1])


def test_dilate_marks_the_nodes_near_marked_cells_or_nodes():
    """foldfree_kernels.dilate against a direct loop: the nodes within m lines of a corner of a
    marked cell (the relax's active sets), and of a marked node (the edge evening's), the grid's
    ring left out; fresh random masks (sparse and dense) and margins, by running counts and by
    boxes, each in parallel rows and serially."""
    from clothgrid.foldfree import _active_nodes
    from clothgrid.foldfree_kernels import _dilate, _dilate_boxes, _dilate_boxes_sized, _dilate_sized, dilate

    _dilate_serial, _dilate_boxes_serial = _dilate_sized.serial, _dilate_boxes_sized.serial

    kernels = (_dilate, _dilate_boxes, _dilate_serial, _dilate_boxes_serial)

    rng = np.random.default_rng()
    for _ in range(60):
        nu, nv = (int(k) for k in rng.integers(3, 30, 2))
        m = int(rng.integers(0, 10))
        cells = rng.random((nu - 1, nv - 1)) < rng.choice([0.0, 0.01, 0.05, 0.3])
        want = np.zeros((nu, nv), bool)
        for ci, cj in np.argwhere(cells):
            want[max(1, ci - m):min(nu - 1, ci + m + 2), max(1, cj - m):min(nv - 1, cj + m + 2)] = True
        got, count = dilate(cells, m + 1, m, nu, nv)
        assert np.array_equal(got, want) and count == want.sum()
        for kernel in kernels:
            got, count = kernel(cells, m + 1, m, nu, nv)
            assert np.array_equal(got, want) and count == want.sum(), kernel
        assert np.array_equal(_active_nodes(cells, m), np.argwhere(want))
        nodes = rng.random((nu, nv)) < 0.05
        want = np.zeros((nu, nv), bool)
        for i, j in np.argwhere(nodes):
            want[max(1, i - m):min(nu - 1, i + m + 1), max(1, j - m):min(nv - 1, j + m + 1)] = True
        got, count = dilate(nodes, m, m, nu, nv)
        assert np.array_equal(got, want) and count == want.sum()
        for kernel in kernels:
            got, count = kernel(nodes, m, m, nu, nv)
            assert np.array_equal(got, want) and count == want.sum(), kernel


def test_over_relaxed_ordered_sweeps_untangle_with_fewer_sweeps(monkeypatch):
    """The ordered sweeps' over-relaxed Newton step (``OVERRELAX``) against the plain one on the
    Roache regions at 80 x 80 nodes, both weights: both untangle every region; the over-relaxed
    sweeps take at most three quarters of the plain sweeps in all (0.68 when measured) and leave a
    smallest corner Jacobian no worse than 0.9 of the plain one's on every region. One grid each
    (no coarser grid first, ``COARSE_RELAX``): the sweeps counted are all of the same grid."""
    import clothgrid.foldfree as ff

    monkeypatch.setattr(ff, "COARSE_RELAX", 10**9)
    omega = ff.OVERRELAX
    assert omega > 1.0
    sweeps = {1.0: 0, omega: 0}
    for path in REGIONS:
        for weights in ("paper", "uniform"):
            length = generate(clothgrid.load_boundary(path), 80, weights=weights)
            jmin = {}
            for w in (1.0, omega):
                monkeypatch.setattr(ff, "OVERRELAX", w)
                pts, info = ff.relax(length.points, dim=length.dim)
                assert info["untangled"] and _folded(pts, length.dim) == 0
                sweeps[w] += info["sweeps"]
                jmin[w] = info["min_corner_jacobian"]
            assert jmin[omega] >= 0.9 * jmin[1.0], (path.stem, weights, jmin)
    assert sweeps[omega] <= 0.75 * sweeps[1.0], sweeps


def test_every_node_is_untangled_from_the_grid_of_every_other_line(monkeypatch):
    """Where the active sets leave folds, every node is untangled starting from the relaxed grid of
    every other line (recursively, ``COARSE_RELAX``): forced there on the Roache regions at 80 x 80
    (no margin at all), it untangles every region, through at least two grids, and leaves a
    smallest corner Jacobian at least 0.8 of the one-grid untangling's (0.86-1.50 when measured,
    in 0.4 of its time)."""
    import clothgrid.foldfree as ff

    monkeypatch.setattr(ff, "MAX_MARGIN", 0)
    monkeypatch.setattr(ff, "WIDE_MARGIN", 0)
    least = ff.COARSE_RELAX
    for path in REGIONS:
        length = generate(clothgrid.load_boundary(path), 80, weights="paper")
        got = {}
        for coarse in (least, 10**9):
            monkeypatch.setattr(ff, "COARSE_RELAX", coarse)
            said = []
            pts, info = ff.relax(length.points, dim=length.dim, margin=0, progress=said.append)
            assert info["untangled"] and _folded(pts, length.dim) == 0
            for sl in (np.s_[0], np.s_[-1], np.s_[:, 0], np.s_[:, -1]):
                assert np.array_equal(pts[sl], length.points[sl])
            got[coarse] = (info, said)
        (multi, said), (single, _) = got[least], got[10**9]
        assert multi["levels"] >= 2 and "levels" not in single
        assert any("every other line first" in s for s in said), said
        assert multi["min_corner_jacobian"] >= 0.8 * single["min_corner_jacobian"], (path.stem, multi, single)


def test_after_a_coarser_grid_only_the_poor_cells_neighbourhoods_are_smoothed(monkeypatch):
    """Where every node was untangled from the grid of every other line, that grid's every interior
    node is smoothed before its interpolation, and on the grid asked for only the nodes within
    ``SMOOTH_MARGIN`` lines of a cell with an angle below ``asin(SMOOTH_SINE)``: forced there on the
    Roache regions at 80 x 80, against smoothing every node (``SMOOTH_SINE`` above 1, the behaviour
    before), no fold, a smallest corner Jacobian at least 0.8 of its (0.83-1.09 when measured), a
    smallest angle as large up to 1 degree or above ``asin(SMOOTH_SINE)``, and under half its
    smoothing work over the regions (0.33 when measured)."""
    import math

    import clothgrid.foldfree as ff
    from clothgrid.quality import sim_figures

    default = ff.SMOOTH_SINE
    monkeypatch.setattr(ff, "MAX_MARGIN", 0)
    monkeypatch.setattr(ff, "WIDE_MARGIN", 0)
    floor = math.degrees(math.asin(default)) - 1.0
    sweeps = ff._sweeps
    total = {}
    for path in REGIONS:
        length = generate(clothgrid.load_boundary(path), 80, weights="paper")
        got = {}
        for sine in (default, 1.01):
            monkeypatch.setattr(ff, "SMOOTH_SINE", sine)
            work = [0]

            def counted(Xs, nodes, delta2, n, tol, work=work):
                done = sweeps(Xs, nodes, delta2, n, tol)
                if delta2 == ff.DELTA_SMOOTH ** 2 and Xs.shape[:2] == length.points.shape[:2]:
                    work[0] += done[0] * len(nodes)
                return done

            monkeypatch.setattr(ff, "_sweeps", counted)
            pts, info = ff.relax(length.points, dim=length.dim, margin=0)
            assert info["untangled"] and _folded(pts, length.dim) == 0 and info["levels"] >= 2
            got[sine] = info["min_corner_jacobian"], sim_figures(pts)["min_angle_deg"], work[0]
            total[sine] = total.get(sine, 0) + work[0]
        (jac, angle, work), (jac_all, angle_all, work_all) = got[default], got[1.01]
        assert jac >= 0.8 * jac_all, (path.stem, got)
        assert angle >= min(angle_all - 1.0, floor), (path.stem, got)
        assert work <= work_all
    assert total[default] < 0.5 * total[1.01], total


@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/patterns is not here")
def test_an_active_set_whose_first_sweeps_add_folds_is_given_up(monkeypatch):
    """A real piece (fs_wahid_layout.svg, piece front, once 4, at the default 10 mm edges) whose poor cells'
    margin gathers folds in its first ``GIVE_UP_SWEEPS`` sweeps (220 -> 286 folded corners) gives
    that set up and untangles every node from the coarser grid at once: untangled, as good a
    smallest corner Jacobian as running the set's rounds out first (0.8 of it at least; the same to
    6 digits when measured), in fewer sweeps (291 against 381)."""
    import clothgrid.foldfree as ff
    from clothgrid.pipeline import generate_piece
    from clothgrid.readers import read_pieces

    src = SHARED / "fs_wahid_layout.svg"
    piece = next(p for p in read_pieces(src) if p.name == "front")
    length = generate_piece(piece, edge_length="10mm", functional="length")
    given, info = ff.relax(length.points, dim=length.dim)
    assert info["untangled"] and info.get("given_up", 0) >= 1 and info["levels"] >= 2
    monkeypatch.setattr(ff, "GIVE_UP_SWEEPS", 10**9)           # never given up: the rounds run out
    kept, info_kept = ff.relax(length.points, dim=length.dim)
    assert info_kept["untangled"] and "given_up" not in info_kept
    assert info["min_corner_jacobian"] >= 0.8 * info_kept["min_corner_jacobian"], (info, info_kept)
    assert info["sweeps"] < info_kept["sweeps"]
    assert _folded(given, length.dim) == 0


@pytest.mark.skipif(not SHARED.is_dir(), reason="../shared/patterns is not here")
def test_the_wide_active_set_is_not_given_up():
    """Only the narrow set is given up early: a GarmentCode front torso at 2 mm edges (628 folded
    cells in its length grid) gives its narrow set up and still untangles, where giving the wide
    set up as well left 2 folded cells."""
    from clothgrid.pipeline import generate_piece
    from clothgrid.readers import read_pieces

    src = SHARED / "gcn_rand_L12WU7204Q_specification.json"
    piece = next(p for p in read_pieces(src) if p.name == "left_ftorso")
    grid = generate_piece(piece, edge_length="2mm")
    assert grid.info["folded_before"] > 0 and grid.info["folded"] == 0 == quality(grid).folded
    assert grid.info["foldfree"].get("given_up") == 1, grid.info["foldfree"]


def test_a_first_round_that_untangles_in_its_first_sweeps_ends_there(monkeypatch):
    """The bundled T-shirt front at 512^2 (uniform weights) folds a few cells at the armholes; its
    narrow set's first ``GIVE_UP_SWEEPS`` sweeps untangle them, and the round ends there (the
    smoothing follows) instead of running all ``RELAX_SWEEPS``: fewer sweeps (60 against 79 when
    measured), and a smallest corner Jacobian and angle within 1 % of the full round's (the same
    Jacobian to 4 digits, 21.80 against 21.85 degrees)."""
    import clothgrid.foldfree as ff
    from clothgrid.quality import sim_figures

    b = clothgrid.load_boundary(Path(clothgrid.__file__).parent / "data" / "tshirt_front.json").resampled(512, 512)
    length = generate(b, weights="uniform")
    assert quality(length).folded > 0
    got = {}
    for look in (ff.GIVE_UP_SWEEPS, 10**9):                    # 10**9: no look, the round runs out
        monkeypatch.setattr(ff, "GIVE_UP_SWEEPS", look)
        pts, info = ff.relax(length.points, dim=length.dim)
        assert info["untangled"] and info["rounds"] == 1 and _folded(pts, length.dim) == 0
        got[look] = info["sweeps"], info["min_corner_jacobian"], sim_figures(pts)["min_angle_deg"]
    (sweeps, jac, angle), (sweeps_full, jac_full, angle_full) = got.values()
    assert sweeps < sweeps_full, got
    assert jac >= 0.99 * jac_full and angle >= 0.99 * angle_full, got


@pytest.mark.parametrize("parallel", [False, True])
def test_cells_below_are_the_cells_whose_smallest_sine_is_below(monkeypatch, parallel, rng):
    """cells_below (most cells passed without a square root) marks exactly the cells whose
    cell_min_sine is below the bound, the grid-corner cells taken as a sine of 1: on fresh grids
    with folds and zero-length edges, and with the bound set to a cell's own smallest sine and the
    floats either side of it, where only the exact sines can tell."""
    import clothgrid.foldfree_kernels as fk

    monkeypatch.setattr(fk, "PARALLEL_CELLS", 0 if parallel else 10**12)
    for trial in range(60):
        nu, nv = (int(n) for n in rng.integers(2, 30, size=2))
        X = np.stack(np.meshgrid(np.arange(nu, dtype=float), np.arange(nv, dtype=float), indexing="ij"), -1)
        X = X * rng.uniform(1e-3, 1e3) + rng.normal(scale=rng.choice([0.05, 0.3, 0.7]), size=X.shape)
        if trial % 4 == 0 and nu > 2:
            X[1, min(1, nv - 1)] = X[1, 0]          # a zero-length edge
        sines = fk.cell_min_sine(X)
        sines[0, 0] = sines[-1, 0] = sines[0, -1] = sines[-1, -1] = 1.0
        pick = sines[rng.integers(sines.shape[0]), rng.integers(sines.shape[1])]
        for bound in (0.34, 0.57, -0.2, 1.5, pick, np.nextafter(pick, 2.0), np.nextafter(pick, -2.0)):
            assert np.array_equal(fk.cells_below(X, bound), sines < bound), (trial, bound)
    # a cell with one reflex corner, in each of its four places (the other three wide open): only
    # that corner's cross product tells it from a good cell
    for k in range(4):
        X = np.stack(np.meshgrid(np.arange(5.0), np.arange(5.0), indexing="ij"), -1)
        c = ((1, 1), (2, 1), (2, 2), (1, 2))
        q, o = c[k], c[(k + 2) % 4]
        X[q] = X[q] + 0.75 * (X[o] - X[q])
        sines = fk.cell_min_sine(X)
        assert sines[1, 1] < -0.3
        for bound in (-0.3, 0.0, 0.34):
            assert fk.cells_below(X, bound)[1, 1] and np.array_equal(fk.cells_below(X, bound), sines < bound)


@pytest.mark.parametrize("parallel", [False, True])
def test_smallest_cell_sine_is_the_arrays_minimum(monkeypatch, parallel, rng):
    """smallest_cell_sine gives cell_min_sine(X).min() with the four grid-corner cells set to 1
    (where there are more than four cells), bit for bit, without the array, and with a cap
    min(that, cap): on fresh grids with folds and zero-length edges, on grids of one to four
    cells, and with a NaN node."""
    import clothgrid.foldfree_kernels as fk

    monkeypatch.setattr(fk, "PARALLEL_CELLS", 0 if parallel else 10**12)
    for trial in range(80):
        nu, nv = (int(n) for n in rng.integers(2, 25, size=2)) if trial % 8 else (2, int(rng.integers(2, 4)))
        X = np.stack(np.meshgrid(np.arange(nu, dtype=float), np.arange(nv, dtype=float), indexing="ij"), -1)
        X += rng.normal(scale=rng.choice([0.05, 0.3, 0.7]), size=X.shape)
        if trial % 5 == 0:
            X[nu // 2, nv // 2] = X[nu // 2, nv // 2 - 1]      # a zero-length edge
        sines = fk.cell_min_sine(X)
        if sines.size > 4:
            sines[0, 0] = sines[-1, 0] = sines[0, -1] = sines[-1, -1] = 1.0
        assert fk.smallest_cell_sine(X) == float(sines.min()), trial
        # a cap: min(smallest, cap) bit for bit, the cap at a cell's own sine and the floats beside it
        some = float(rng.choice(sines.ravel()))
        for cap in (some, np.nextafter(some, -2.0), np.nextafter(some, 2.0), float(rng.uniform(-1, 1)), 0.9):
            assert fk.smallest_cell_sine(X, cap) == min(float(sines.min()), cap), (trial, cap)
    X = np.stack(np.meshgrid(np.arange(6.0), np.arange(7.0), indexing="ij"), -1)
    X[3, 3] = np.nan
    sines = fk.cell_min_sine(X)
    sines[0, 0] = sines[-1, 0] = sines[0, -1] = sines[-1, -1] = 1.0
    assert fk.smallest_cell_sine(X) == float(sines.min())


@pytest.mark.parametrize("parallel", [False, True])
def test_corner_cells_after_a_sweep_give_corner_min(monkeypatch, parallel, rng):
    """CornerCells measures again only the cells with a corner at the nodes a sweep may move (the
    rest once): after sweeps over fresh active sets of a tangled grid (a block, scattered nodes,
    every interior node, none) its minimum and count are corner_min's of the whole grid, bit for
    bit, every time; and a node left out of its set is seen to matter (a sweep over it is missed)."""
    import clothgrid.foldfree_kernels as fk

    monkeypatch.setattr(fk, "PARALLEL_CELLS", 0 if parallel else 10**12)
    missed = 0
    for trial in range(12):
        nu, nv = (int(n) for n in rng.integers(5, 40, size=2))
        X = np.stack(np.meshgrid(np.arange(nu, dtype=float), np.arange(nv, dtype=float), indexing="ij"), -1)
        X += rng.normal(scale=0.45, size=X.shape)               # folds
        for skip in (True, False):
            mask = np.zeros((nu, nv), bool)
            kind = (trial + skip) % 4
            if kind == 0:
                i0, j0 = int(rng.integers(1, nu - 1)), int(rng.integers(1, nv - 1))
                mask[i0:i0 + int(rng.integers(1, 6)), j0:j0 + int(rng.integers(1, 6))] = True
            elif kind == 1:
                mask = rng.random((nu, nv)) < 0.1
            elif kind == 2:
                mask[:] = True
            mask[0], mask[-1], mask[:, 0], mask[:, -1] = False, False, False, False
            nodes = np.argwhere(mask).astype(np.int64)
            cells = fk.CornerCells(X, skip, nodes)
            assert cells.figures() == fk.corner_min(X, skip)
            for _ in range(3):
                fk.sweep_nodes(X, nodes, 0.01, 3, 0.0, 1.0)
                assert cells.moved(X) == fk.corner_min(X, skip), (trial, skip)
            if len(nodes):              # a sweep over nodes outside the set: their cells are missed
                cells = fk.CornerCells(X, skip, np.zeros((0, 2), np.int64))
                fk.sweep_nodes(X, nodes, 0.01, 3, 0.0, 1.0)
                missed += cells.moved(X) != fk.corner_min(X, skip)
    assert missed > 0
    assert fk.CornerCells(np.zeros((1, 5, 2)), True, np.zeros((0, 2), np.int64)).figures() == \
        fk.corner_min(np.zeros((1, 5, 2)), True)


def test_grid_from_plane_is_the_copy_with_its_interior_set(rng):
    """foldfree_kernels.grid_from_plane makes the 3D grid of planar coordinates in one pass: the same
    array, bit for bit, as a copy of the grid with its interior set by axes_from_plane (and z = 0),
    for every frame that only swaps and negates the x and y axes."""
    import clothgrid.foldfree_kernels as fk

    for axes in ([(0, 1.0), (1, 1.0)], [(1, -1.0), (0, 1.0)], [(0, -1.0), (1, -1.0)], [(1, 1.0), (0, -1.0)]):
        nu, nv = (int(n) for n in rng.integers(3, 60, size=2))
        R = rng.normal(size=(nu, nv, 3))
        X = rng.normal(size=(nu, nv, 2))
        want = R.copy()
        fk.axes_from_plane(X, axes, None, 1.0, want)
        want[1:-1, 1:-1, 2] = 0.0
        got = fk.grid_from_plane(R, X, axes)
        assert np.array_equal(got, want) and not np.shares_memory(got, R)
        assert np.array_equal(np.signbit(got), np.signbit(want))


@pytest.mark.parametrize("parallel", [False, True])
def test_unscale_in_plane_is_numpys_multiply_and_add(monkeypatch, parallel, rng):
    """foldfree_kernels.unscale_in_plane undoes relax's shift and scale in one pass: the moved
    interior nodes as NumPy's ``X * scale + shift``, every other node (the boundary, and interior
    nodes not moved, even if marked on the boundary) as to_plane gives it from the 3D grid, bit for bit."""
    import clothgrid.foldfree_kernels as fk
    from clothgrid.foldfree import _axis_map, plane_frame, to_plane

    monkeypatch.setattr(fk, "PARALLEL_CELLS", 0 if parallel else 10**12)
    for _ in range(4):
        nu, nv = (int(n) for n in rng.integers(3, 50, size=2))
        R = np.zeros((nu, nv, 3))
        R[..., :2] = rng.normal(size=(nu, nv, 2)) * 10.0 ** rng.uniform(-3, 3)
        centre, basis = plane_frame(R, 2)
        X = rng.normal(size=(nu, nv, 2))
        moved = rng.random((nu, nv)) < 0.5
        shift, scale = rng.normal(size=2), float(10.0 ** rng.uniform(-3, 3))
        want = to_plane(R, centre, basis)
        inner = moved.copy()
        inner[[0, -1]] = inner[:, [0, -1]] = False
        want[inner] = X[inner] * scale + shift
        fk.unscale_in_plane(X, R, moved, _axis_map(centre, basis), shift, scale)
        assert np.array_equal(X, want)


def test_fold_free_points_write_only_the_moved_nodes_and_put_them_back(rng):
    """generate's fold-free grid: only the nodes the relax or the evening may have moved take X's
    values (written into the length grid itself where they are few, with the same values a new
    grid would get), every other node stays the length grid's bit for bit, and the length grid
    comes back as it was where the result is not kept; many moved nodes go to a new array."""
    from clothgrid.foldfree import _with_interior, plane_frame, to_plane
    from clothgrid.generate import _fold_free_points

    nu, nv = 40, 30
    R = np.zeros((nu, nv, 3))
    R[..., :2] = np.stack(np.meshgrid(np.arange(nu, dtype=float), np.arange(nv, dtype=float), indexing="ij"), -1)
    R[..., :2] += rng.normal(scale=0.1, size=(nu, nv, 2))
    R0 = R.copy()
    centre, basis = plane_frame(R, 2)
    X = np.ascontiguousarray(to_plane(R, centre, basis))
    moved = np.zeros((nu, nv), bool)
    moved[5:9, 6:10] = True
    touched = [np.array([[20, 20], [21, 20]]), np.array([[21, 20], [30, 3]])]
    changed = moved.copy()
    for t in touched:
        changed[t[:, 0], t[:, 1]] = True
    X[changed] += rng.normal(scale=0.05, size=(int(changed.sum()), 2))
    want = _with_interior(R0, X, centre, basis, 2)         # a new grid with X's interior
    points, put_back, nodes = _fold_free_points(R, X, centre, basis, 2, moved, touched)
    assert points is R and np.array_equal(points, want)
    assert np.array_equal(nodes, np.argwhere(changed))       # the nodes written, for the quality after
    assert np.array_equal(points[~changed], R0[~changed])
    put_back()
    assert np.array_equal(R, R0)
    many = np.ones((nu, nv), bool)
    points, put_back, nodes = _fold_free_points(R, X, centre, basis, 2, many, [])
    assert nodes is None and points is not R and np.array_equal(points, want) and np.array_equal(R, R0)
    X[21, 20] = np.nan        # a moved node gone non-finite: one clear error, the length grid as it was
    for mask in (moved, many):
        with pytest.raises(InputError, match=r"the fold-free step gave a grid with non-finite .* node \(21, 20\)"):
            _fold_free_points(R, X, centre, basis, 2, mask, touched)
        assert np.array_equal(R, R0)
