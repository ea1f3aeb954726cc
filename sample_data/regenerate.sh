#!/bin/sh
# Regenerate the synthetic sample tests. Each FRF file gets its exact modes beside it
# (<name>.modes.json). Same seeds, same files.
set -e
cd "$(dirname "$0")"
AUTOMODAL=${AUTOMODAL:-automodal}

# (a) 6-DOF chain grounded at DOF 1: all 6 DOFs measured, force at DOF 6, receptance,
#     Rayleigh damping (1 % at the first and last mode), 1 % proportional noise, 1000 lines.
$AUTOMODAL simulate chain6.h5 --system chain --dof 6 --outputs all --inputs 6 \
    --quantity displacement --damping rayleigh --noise 0.01 --lines 1000 --seed 1

# (b) 3x4 grid of masses (12 modes), 8 sensors, forces at two opposite corners, accelerance,
#     non-proportional damping (complex modes), 1 % proportional noise, 1000 lines.
$AUTOMODAL simulate grid_mimo.h5 --system grid --grid 3 4 --outputs 1,2,3,5,7,8,10,12 \
    --inputs 1,12 --quantity acceleration --damping nonproportional --noise 0.01 \
    --lines 1000 --seed 2

# (c) SISO driving point of an 8-DOF chain (sensor and force at the free end), mobility,
#     0.5 % proportional noise: the spatial-aliasing case (8 modes, one channel).
$AUTOMODAL simulate chain8_siso.h5 --system chain --dof 8 --outputs 8 --inputs 8 \
    --quantity velocity --noise 0.005 --lines 1000 --seed 3
