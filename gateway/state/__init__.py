"""What the gateway learned of its IMU, kept across starts: the store and the warm start."""
