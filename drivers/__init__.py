"""Device contracts, real backends, protocol codecs and the simulated plant and devices."""
