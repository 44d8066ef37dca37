"""The flight pass's stages, from the IMU's samples to the output words: filters, estimator, rate and angle
control, mixer, stick shaping, receiver."""
