"""uav-swarm: place and fly a swarm of up to 10 UAVs over a moving crowd."""

__version__ = "0.2.0"
