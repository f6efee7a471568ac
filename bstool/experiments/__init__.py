"""The paper's experiments (§5) and the ones it proposed: fault tolerance, extrapolation beyond
MAX_TRANS, steering by leg rotation, path shape and the spread over leg rotations."""
