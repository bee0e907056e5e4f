"""Every URDF of the example-robot-data package that Pinocchio loads also
loads in rbdkit, and its dynamics agree with Pinocchio's.

For each file, fixed base and free-flyer base:
  * mimic=False (Pinocchio's default: a mimic joint is an independent
    coordinate) against Pinocchio's default model;
  * mimic=True (folded couplings) against Pinocchio's default model through
    the coupling map G (reduced quantities Gᵀ(·)G), and against Pinocchio's
    own mimic joints (buildModelFromUrdf(..., mimic=True)) where it reads them.
RNEA, the full mass matrix (CRBA) and ABA at random states agree to
1e-9 · max(1, max|reference|). Coordinates are matched by joint name
(pinref.Reference): urdfdom orders sibling joints by name, rbdkit by document
order, and Pinocchio's continuous joints have (cos, sin) coordinates.

Nothing is skipped: a file that is not compared in some way is listed below
with its reason, and the test checks that the reason still holds.

Counts (example-robot-data 6.0.0, Pinocchio 4.1): 69 files found, 68 load in
Pinocchio, 68 load in rbdkit (mimic False and True, fixed and floating base),
68 compared (66 with coordinates on a fixed base; the 2 without are compared
with a free-flyer base); Pinocchio's own mimic joints compared on 5 files.
"""

import glob
import importlib.metadata
import os
import sys
import warnings

import numpy as np
import pinocchio as pin
import pytest

import rbdkit
from pinref import Reference, compare_dynamics


def robots_dir():
    """the robots/ folder of the installed example-robot-data package (a cmeel
    package: <site-packages>/cmeel.prefix/share/example-robot-data/robots)"""
    tail = os.path.join("share", "example-robot-data", "robots")
    candidates = []
    try:
        for f in importlib.metadata.files("example-robot-data") or []:
            p = str(f.locate())
            if p.endswith(".urdf") and os.sep + tail + os.sep in p:
                candidates.append(p[:p.index(os.sep + tail + os.sep)] + os.sep + tail)
                break
    except importlib.metadata.PackageNotFoundError:
        pass
    # the cmeel prefix next to Pinocchio, or on the path
    pin_prefix = os.path.abspath(os.path.join(os.path.dirname(pin.__file__), *[os.pardir] * 4))
    candidates += [os.path.join(pin_prefix, tail)]
    candidates += [os.path.join(p, "cmeel.prefix", tail) for p in sys.path if p]
    for c in candidates:
        if os.path.isdir(c):
            return c
    raise RuntimeError("example-robot-data is not installed (pip install example-robot-data): no robots folder "
                       f"among {candidates}")


ROBOTS = robots_dir()
FILES = sorted(os.path.relpath(p, ROBOTS) for p in glob.glob(os.path.join(ROBOTS, "**", "*.urdf"), recursive=True))

# files Pinocchio does not load (the test checks that it still rejects them)
PIN_REJECTS = {
    "ur_description/urdf/ur3.urdf": "an empty <robot> left by xacro (no name, no links); urdfdom rejects it",
}
# files whose mimic joints Pinocchio's mimic=True reader rejects ("the parent
# joint of the mimic joint is not in the kinematic tree"): their folded
# couplings are compared against Pinocchio's default model through G only
PIN_MIMIC_REJECTS = {
    "alex_description/urdf/alex_psyonic_hands.urdf": "mimics of joints that the file does not define",
    "romeo_description/urdf/romeo.urdf": "a mimic target ordered after its mimic by urdfdom",
    "talos_data/robots/talos_full_v2.urdf": "a mimic target ordered after its mimic by urdfdom",
    "talos_data/robots/talos_full_v2_box.urdf": "a mimic target ordered after its mimic by urdfdom",
}
# files with no coordinates on a fixed base: a single rigid body fixed to the
# world has no dynamics; they are compared with a free-flyer base only
NO_COORDINATES = {
    "hector_description/robots/quadrotor_base.urdf": "one rigid body (a quadrotor)",
    "iris_description/robots/iris_simple.urdf": "one rigid body (a quadrotor without its rotors)",
}
# files whose mass matrix is singular (joints that move no mass): ABA has no
# answer; rbdkit raises, Pinocchio's ABA returns NaN. RNEA and CRBA are compared.
SINGULAR = {
    "romeo_description/urdf/romeo.urdf": "massless finger links (LFinger2x, LFinger3x, RHand...)",
    "romeo_description/urdf/romeo_laas_small.urdf": "massless gripper links (r_gripper_joint)",
}


def load_rbdkit(path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the files' doubtful inertias and limits are reported, not errors
        return rbdkit.Model.from_urdf(path, **kw)


def reference(path, fb, mimic, pin_mimic=False):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Reference(path, fb, mimic=mimic, pin_mimic=pin_mimic)


def test_files_found():
    # a missing or emptied package fails here, never skips
    assert len(FILES) >= 69, f"{len(FILES)} URDF files under {ROBOTS}"
    for listed in (PIN_REJECTS, PIN_MIMIC_REJECTS, NO_COORDINATES, SINGULAR):
        for f in listed:
            assert f in FILES, f"{f} is listed but not in the package"


@pytest.mark.parametrize("rel", FILES)
def test_loads_and_agrees_with_pinocchio(rel):
    path = os.path.join(ROBOTS, rel)
    if rel in PIN_REJECTS:
        with pytest.raises(Exception):
            pin.buildModelFromUrdf(path)
        return
    pin.buildModelFromUrdf(path)  # Pinocchio loads it, so rbdkit must
    for fb in (False, True):
        base = "floating" if fb else "fixed"
        for mimic in (False, True):
            model = load_rbdkit(path, floating_base=fb, mimic=mimic)
            if model.nv == 0:
                assert rel in NO_COORDINATES and not fb, f"{rel} ({base}) has no coordinates"
                continue
            compare_dynamics(reference(path, fb, mimic), f"{rel} ({base}, mimic={mimic})", rel in SINGULAR)
        if rel in PIN_MIMIC_REJECTS:
            with pytest.raises(ValueError, match="mimic"):
                pin.buildModelFromUrdf(path, mimic=True)
        elif load_rbdkit(path, floating_base=fb, mimic=True).has_mimic:
            compare_dynamics(reference(path, fb, True, pin_mimic=True), f"{rel} ({base}, Pinocchio's mimic joints)",
                    rel in SINGULAR)
