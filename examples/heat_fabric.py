"""Heat through a layered fabric cross-section: skin at 34 C, air at 20 C (clothgrid.heat).

A 10 mm wide, 6 mm thick section through clothing on skin (y up, away from the
body): a 0.5 mm air gap next to the skin, a 1.5 mm cotton shirt, a 2 mm wool
layer whose fibres hold air pockets (a 1e4 contrast would be a metal snap; here
wool 0.05 and trapped air 0.025 W/(m K)), a 0.5 mm windproof shell with a
metal press stud (50 W/(m K), 2000x the air around it), and 1.5 mm of outside
air that the top side's convection (h = 10 W/(m^2 K), 20 C) stands for beyond.
Left and right are insulated (the section repeats sideways). Writes
``heat_fabric.png`` (field and isotherms) and prints the heat loss per square
metre of skin and the energy balance.

    python examples/heat_fabric.py [OUT.png]
"""

from __future__ import annotations

import sys

import numpy as np

from clothgrid.heat import HeatProblem, convection, solve_steady


def fabric(nx: int = 400, ny: int = 240, width: float = 0.010, height: float = 0.006) -> np.ndarray:
    """Conductivity per cell, W/(m K), ``(nx, ny)``: the layers bottom (skin) to top (air)."""
    dy = height / ny
    y = (np.arange(ny) + 0.5) * dy
    x = (np.arange(nx) + 0.5) * width / nx
    k = np.empty((nx, ny))
    layers = [(0.0005, 0.026), (0.0020, 0.06), (0.0040, 0.05), (0.0045, 0.15), (height, 0.026)]  # top edge, k
    lo = 0.0
    for top, kv in layers:
        k[:, (y >= lo) & (y < top)] = kv
        lo = top
    wool = (y >= 0.0020) & (y < 0.0040)
    X, Y = np.meshgrid(x, y, indexing="ij")
    pockets = (np.sin(2 * np.pi * X / 0.0013) * np.sin(2 * np.pi * Y / 0.0007) > 0.55) & wool[None, :]
    k[pockets] = 0.025                                 # air trapped between wool fibres
    stud = (np.abs(X - 0.006) < 0.0008) & (Y >= 0.0040) & (Y < 0.0045)
    k[stud] = 50.0                                     # a metal press stud in the shell
    return k


def main(out: str = "heat_fabric.png") -> None:
    k = fabric()
    problem = HeatProblem(k, (0.010, 0.006), bottom=34.0, top=convection(10.0, 20.0))
    res = solve_steady(problem, tol=1e-9, error_bound=True, progress=print)
    flows = res.heat_flows()
    print(f"heat loss {flows['bottom'] / 0.010:.1f} W/m2 of skin; balance {sum(flows.values()):.2e} W/m; "
          f"error bound {res.info['error_bound']:.1e} K; contrast {k.max() / k.min():.0f}")
    print(f"outer surface {res.temperature[:, -1].min():.2f} to {res.temperature[:, -1].max():.2f} C")
    from clothgrid.heat import plot_temperature

    plot_temperature(res, out, title="Layered fabric on skin (34 C) in air (20 C, h = 10 W/m2K)")
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])
