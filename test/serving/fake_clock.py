"""A fake clock for the serving tests: ROS time (ns) that moves only when slept on or advanced."""


class FakeClock:
    """``clock()``: ROS time (ns); ``timer()``: the same in s (the monotonic timer); ``sleep(s)`` advances
    it and runs every hook with the new time (a fake streamer, a cancel due at some time)."""

    def __init__(self, ns: int):
        self.ns, self.hooks = ns, []

    def __call__(self) -> int:
        return self.ns

    def timer(self) -> float:
        return self.ns * 1e-9

    def advance(self, s: float) -> None:
        self.ns += round(s * 1e9)

    def sleep(self, s: float) -> None:
        self.ns += max(1, round(s * 1e9))
        for hook in list(self.hooks):
            hook(self.ns)
