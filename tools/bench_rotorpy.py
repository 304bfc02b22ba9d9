"""One RotorPy 3.0.0 flight at 1 kHz, timed, for tools/bench_rotorpy.sh.

Usage: python tools/bench_rotorpy.py SECONDS (in the venv of
tests/rotorpy/requirements.txt). Prints "STEPS ELAPSED": the steps RotorPy
took and the wall time around ``sim.run`` alone (its loop and the packing of
its results), not the imports or the set-up.

The flight: RotorPy's Multirotor and SE3Control with its Hummingbird
parameters (the airframe of the cross-check, tests/rotorpy/), following a
ThreeDCircularTraj circle of radius 2 m at 0.5 rad/s in the horizontal plane
(the half-width and rate of tools/scenarios/figure-eight-geometric.toml),
centred 2 m behind the start so that it starts where the vehicle does.
Everything else is RotorPy's default: no wind, its IMU and motion capture
(noisy, sampled every step), the null estimator, the rotor aerodynamics and
scipy's RK45 over each step.
"""

import sys
import time

import numpy as np
from rotorpy.controllers.quadrotor_control import SE3Control
from rotorpy.environments import Environment
from rotorpy.trajectories.circular_traj import ThreeDCircularTraj
from rotorpy.vehicles.hummingbird_params import quad_params
from rotorpy.vehicles.multirotor import Multirotor

RADIUS_M = 2.0
RATE_RAD_S = 0.5
SIM_RATE_HZ = 1000


def main():
    t_final = float(sys.argv[1])
    np.random.seed(0)  # the sensors' noise: the same flight every run
    freq = RATE_RAD_S / (2.0 * np.pi)
    sim = Environment(
        vehicle=Multirotor(quad_params),
        controller=SE3Control(quad_params),
        trajectory=ThreeDCircularTraj(
            center=np.array([-RADIUS_M, 0.0, 0.0]),
            radius=np.array([RADIUS_M, RADIUS_M, 0.0]),
            freq=np.array([freq, freq, 0.0]),
        ),
        sim_rate=SIM_RATE_HZ,
    )
    start = time.perf_counter()
    result = sim.run(t_final=t_final, use_mocap=False, terminate=False, plot=False,
                     animate_bool=False, verbose=False)
    elapsed = time.perf_counter() - start
    if "TIMEOUT" not in str(result["exit"]):
        sys.exit(f"bench_rotorpy.py: RotorPy's flight ended early: {result['exit']}")
    print(len(result["time"]) - 1, elapsed)


if __name__ == "__main__":
    main()
