"""The GIL during a render, Ctrl-C, and memory over many renders. Each test prints its figure."""

import os
import signal
import threading
import time

import pytest

import nimbus


def report(capsys, line):
    with capsys.disabled():
        print(f"\n  figure: {line}")


def test_the_gil_is_released_while_rendering(cloud, capsys):
    scene = nimbus.load(cloud)
    count = [0]
    stop = threading.Event()

    def counter():
        while not stop.is_set():
            count[0] += 1

    thread = threading.Thread(target=counter)
    thread.start()
    try:
        time.sleep(0.05)
        before = count[0]
        start = time.monotonic()
        nimbus.render(scene, spp=64, width=160)
        elapsed = time.monotonic() - start
        during = count[0] - before
    finally:
        stop.set()
        thread.join()
    report(capsys, f"a Python thread counted {during} times during a {elapsed:.2f} s render")
    # Holding the GIL, the render would let the counter run only at the waits of a switch interval (5 ms).
    assert elapsed > 0.2, "the render is long enough to tell"
    assert during > 20_000 * elapsed, f"{during} counts in {elapsed:.2f} s"


def test_ctrl_c_cancels_a_render_within_a_second(cloud, capsys):
    scene = nimbus.load(cloud)
    sent = []

    def interrupt():
        sent.append(time.monotonic())
        os.kill(os.getpid(), signal.SIGINT)

    # A process started in the background by a non-interactive shell inherits SIGINT ignored, and Python then
    # installs no KeyboardInterrupt handler: the test needs Python's own (that is what a user at a terminal has).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.5, interrupt)
    timer.start()
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        # The time limit bounds the render should the interrupt be lost: the test then fails ("did not raise")
        # after 30 s instead of rendering 100,000 spp for hours.
        nimbus.render(scene, spp=100_000, width=320, time_limit=30.0)
    latency = time.monotonic() - sent[0]
    timer.join()
    signal.signal(signal.SIGINT, previous)
    report(capsys, f"SIGINT {sent[0] - start:.2f} s into a render: KeyboardInterrupt after {latency * 1000:.0f} ms")
    assert latency < 1.0
    # The interrupted render left nothing running: the next one renders normally.
    assert nimbus.render(scene, spp=1, width=8).stats["samples_per_pixel"] == 1


def test_an_exception_in_progress_cancels_and_propagates(cloud):
    scene = nimbus.load(cloud)
    calls = []

    def progress(done, total):
        calls.append(done)
        raise RuntimeError(f"stop at {done}")

    start = time.monotonic()
    with pytest.raises(RuntimeError, match="stop at"):
        # Progress comes after each of about 16 passes: the first pass is 1/16 of the render.
        nimbus.render(scene, spp=1600, width=64, progress=progress)
    cancelled = time.monotonic() - start
    assert len(calls) == 1
    start = time.monotonic()
    nimbus.render(scene, spp=1600, width=64)
    whole = time.monotonic() - start
    assert cancelled < whole / 4, f"cancelled after {cancelled:.2f} s of a {whole:.2f} s render"


def rss_bytes():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


@pytest.mark.skipif(not os.path.exists("/proc/self/statm"), reason="reads RSS from /proc (Linux)")
def test_fifty_renders_leave_rss_flat(cloud, capsys):
    scene = nimbus.load(cloud)
    sizes = []

    def once():
        image = nimbus.render(scene, spp=2, width=256)
        sizes.append(sum(layer.nbytes for layer in image.layers.values()))
        image._repr_png_()

    for _ in range(10):  # allocator arenas and thread pools settle
        once()
    settled = rss_bytes()
    for _ in range(50):
        once()
    grown = rss_bytes() - settled
    leak = 50 * sizes[-1]
    report(capsys, f"RSS {settled / 2**20:.1f} MiB after 10 renders, {grown / 2**20:+.2f} MiB after 50 more "
                   f"(leaking each image's layers alone would add {leak / 2**20:.0f} MiB)")
    # The allocator's arenas move RSS by a few MiB either way (measured: -0.1 to +4.7 MiB); a leak of the
    # layers alone, without the film and the layers' copies, would be a quarter of `leak` at the least.
    assert grown < leak / 4
