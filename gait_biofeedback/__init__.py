"""gait_biofeedback: wearable-IMU gait biofeedback for stroke rehabilitation (ROS 2 Jazzy)."""

import os

# The core's linear algebra works on small matrices, sample by sample or per stride: BLAS threads do
# not speed it up, and on a busy 2-core machine (the live graph, two test workers, a batch on Dask)
# their spinning made a banded Cholesky 35x slower (test_spatial's pyshoe test: 7 s single-threaded,
# 260 s with OpenBLAS's default threads beside one other busy process). A value set by the user wins;
# it only takes effect when numpy is imported after this package.
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

__version__ = "0.1.0"
