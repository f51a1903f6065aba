#!/usr/bin/python3
"""The selection app in a real browser: Debian's Chromium, driven by Selenium, against a real
gvd-server on loopback.

Each answer the page shows is judged here, by an exact oracle written for this test (distances
in double precision from the sites' geometry, Bezier curves sampled and refined on the curve
itself), not by the server.

Usage: selection_test.py --server PATH/gvd-server --out DIR [unittest arguments, e.g. -k Hover]
DIR receives the screenshots and hover-latency figures.
"""

import argparse
import json
import math
import os
import random
import shutil
import sys
import tempfile
import time
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import gvdtest  # noqa: E402  (the server and the oracle)
from gvdtest import bezier_point, distance, points_of, slack, value  # noqa: E402

ARGS = None  # --server, --out

try:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys
except ImportError as e:  # a failure, not a skip: tests/run-tests.sh installs it
    sys.exit(f"selenium is missing ({e}): install python3-selenium, chromium and chromium-driver "
             "(tests/run-tests.sh does)")

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"


# ---- the server and the oracle: tests/gvdtest.py --------------------------------------------

def Server(*flags):
    return gvdtest.Server(ARGS.server, *flags)


def P(x, y):
    return {"x": x, "y": y}


def mixed_sites(seed):
    """Every kind, with weights (which Pick ignores), coincident points, sites outside the
    window [0, 100]^2, and a huge weight; paths of one and of two subpaths, with a side."""
    rnd = random.Random(seed)
    u = rnd.uniform
    sites = []
    for i in range(40):
        sites.append({"id": f"pt{i}", "point": P(u(0, 100), u(0, 100))})
    for i in range(10):
        x, y = u(0, 100), u(0, 100)
        sites.append({"id": f"seg{i}", "segment": {"a": P(x, y), "b": P(x + u(-15, 15), y + u(-15, 15))}})
    for i in range(6):
        pts = [P(u(0, 100), u(0, 100))]
        for _ in range(4):
            pts.append(P(pts[-1]["x"] + u(2, 8), pts[-1]["y"] + u(-6, 6)))
        sites.append({"id": f"line{i}", "polyline": {"points": pts}})
    for i in range(6):
        cx, cy, r, n = u(5, 95), u(5, 95), u(2, 7), 3 + i % 4
        side = ["SIDE_UNSPECIFIED", "SIDE_INSIDE", "SIDE_OUTSIDE"][i % 3]
        sites.append({"id": f"poly{i}", "polygon": {
            "vertices": [P(cx + r * math.cos(2 * math.pi * k / n), cy + r * math.sin(2 * math.pi * k / n)) for k in range(n)],
            "side": side}})
    for i in range(6):
        x, y = u(0, 100), u(0, 100)
        sites.append({"id": f"curve{i}", "bezier": {
            "controlPoints": [P(x, y), P(x + u(-10, 10), y + u(-10, 10)), P(x + u(-10, 10), y + u(-10, 10)),
                              P(x + u(-12, 12), y + u(-12, 12))],
            "tolerance": 0.01}})
    for i in range(4):  # one object each: a rounded frame of lines and cubics, a square with a hole
        x, y, w = u(5, 85), u(5, 85), u(6, 10)
        k = 0.5523 * w / 4
        if i % 2 == 0:
            outer = {"points": [P(x + w / 4, y), P(x + w, y), P(x + w, y + w), P(x, y + w), P(x, y + w / 4),
                                P(x, y + w / 4 - k), P(x + w / 4 - k, y), P(x + w / 4, y)],
                     "degrees": [1, 1, 1, 1, 3], "closed": True}
            path = {"subpaths": [outer, {"points": [P(x + w / 2, y + w / 2), P(x + w, y + 1.5 * w)]}],
                    "tolerance": 0.01}
        else:
            square = lambda a, b, s: [P(a, b), P(a + s, b), P(a + s, b + s), P(a, b + s)]
            path = {"subpaths": [{"points": square(x, y, w), "closed": True},
                                 {"points": square(x + w / 4, y + w / 4, w / 2), "closed": True}],
                    "fillRule": "FILL_RULE_EVEN_ODD", "side": "SIDE_OUTSIDE" if i == 1 else "SIDE_INSIDE"}
        sites.append({"id": f"path{i}", "path": path})
    sites.append({"id": "twin-a", "point": P(50.5, 50.5)})
    sites.append({"id": "twin-b", "point": P(50.5, 50.5)})
    sites.append({"id": "outside", "point": P(-8, 40)})
    sites.append({"id": "across", "segment": {"a": P(95, 70), "b": P(115, 75)}})
    sites.append({"id": "heavy", "point": P(70, 20), "additiveWeight": 1e6, "multiplicativeWeight": 50})
    return sites


# ---- the browser ----------------------------------------------------------------------------

def browser(width=1280, height=800):
    if not (os.access(CHROMIUM, os.X_OK) and os.access(CHROMEDRIVER, os.X_OK)):
        raise AssertionError(f"{CHROMIUM} and {CHROMEDRIVER} are needed: install chromium and chromium-driver "
                             "(tests/run-tests.sh does)")
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    profile = tempfile.mkdtemp(prefix="gvd-chromium-")
    for flag in ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--no-first-run", "--disable-extensions", f"--window-size={width},{height}",
                 f"--user-data-dir={profile}"]:
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.profile_dir = profile
    return driver


def close(driver):
    profile = driver.profile_dir
    driver.quit()
    shutil.rmtree(profile, ignore_errors=True)


def page(driver, expr):
    return driver.execute_script(f"return {expr};")


def wait(driver, expr, timeout=30, what=None):
    deadline = time.monotonic() + timeout
    while True:
        value = page(driver, expr)
        if value:
            return value
        if time.monotonic() > deadline:
            logs = "\n".join(str(l) for l in driver.get_log("browser"))
            raise AssertionError(f"timed out waiting for {what or expr}; page error: "
                                 f"{page(driver, 'window.gvd && window.gvd.error')}\n{logs}")
        time.sleep(0.02)


def open_scene(driver, server, scene, token=None, min_version=0):
    url = f"{server.url}/?scene={scene}" + (f"&token={token}" if token else "")
    driver.get(url)
    wait(driver, f"window.gvd && window.gvd.ready && window.gvd.sceneId === '{scene}' && "
                 f"window.gvd.frameVersion >= {min_version}", what=f"scene {scene} drawn")
    return driver.find_element(By.ID, "overlay")


class Pointer:
    """Moves the real pointer over the overlay canvas, at canvas pixel (cx, cy)."""

    def __init__(self, driver):
        self.driver = driver
        self.overlay = driver.find_element(By.ID, "overlay")
        r = page(driver, "document.getElementById('overlay').getBoundingClientRect().toJSON()")
        self.width, self.height = r["width"], r["height"]

    def actions(self):
        return ActionChains(self.driver, duration=0)

    def offset(self, cx, cy):  # Selenium's offsets are from the element's centre
        return int(round(cx - self.width / 2)), int(round(cy - self.height / 2))

    def hover(self, cx, cy):
        """Moves there and waits for the page's answer to that very position."""
        seq = page(self.driver, "window.gvd.hoverSeq")
        self.actions().move_to_element_with_offset(self.overlay, *self.offset(cx, cy)).perform()
        return wait(self.driver,
                    f"window.gvd.hoverSeq > {seq} && window.gvd.hover.at && "
                    f"Math.abs(window.gvd.hover.at[0] - {cx}) <= 1 && Math.abs(window.gvd.hover.at[1] - {cy}) <= 1 "
                    f"&& window.gvd.hover", what=f"the hover answer at {cx},{cy}")

    def click(self, cx, cy):
        self.actions().move_to_element_with_offset(self.overlay, *self.offset(cx, cy)).click().perform()

    def drag(self, start, end, steps=8):
        chain = self.actions().move_to_element_with_offset(self.overlay, *self.offset(*start)).click_and_hold()
        for k in range(1, steps + 1):
            t = k / steps
            chain = chain.move_to_element_with_offset(
                self.overlay, *self.offset(start[0] + t * (end[0] - start[0]), start[1] + t * (end[1] - start[1])))
        chain.release().perform()


def text(driver, element_id):
    return driver.find_element(By.ID, element_id).text


def screenshot(driver, name):
    os.makedirs(ARGS.out, exist_ok=True)
    path = os.path.join(ARGS.out, name)
    driver.save_screenshot(path)
    return path


# ---- the tests ------------------------------------------------------------------------------

class SelectionTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.server = Server("--max-message-bytes", "1000000")

    @classmethod
    def tearDownClass(cls):
        cls.server.stop()

    def create(self, scene, sites, size=1024):
        self.server.ok("CreateScene", {"sceneId": scene, "window": {"minX": 0, "minY": 0, "maxX": 100, "maxY": 100},
                                       "widthPx": size, "heightPx": size})
        return int(self.server.ok("UpsertSites", {"sceneId": scene, "sites": sites})["version"])

    def sites(self, scene):
        return {s["id"]: s for s in self.server.ok("ListSites", {"sceneId": scene, "pageSize": 10000}).get("sites", [])}

    def setUp(self):
        self.drivers = []

    def tearDown(self):
        for d in self.drivers:
            close(d)

    def browser(self):
        d = browser()
        self.drivers.append(d)
        return d

    def check_hover(self, driver, answer, sites, max_distance=0):
        """The panel's id and distance against the oracle at the point the page answered for."""
        q = (answer["x"], answer["y"])
        truth = {id: distance(q, s) for id, s in sites.items()}
        best = min(truth[id] - slack(s) for id, s in sites.items())
        shown_id = text(driver, "hover-id")
        if max_distance and best > max_distance + 1e-9:
            self.assertTrue(shown_id.startswith("none within"), f"at {q}: {shown_id}, nearest at {best}")
            return None
        if max_distance and min(truth[id] + slack(s) for id, s in sites.items()) > max_distance:
            return None  # within the slack of the limit: either answer is right
        self.assertIn(shown_id, sites, f"at {q}: the panel shows {shown_id!r}")
        shown_distance = float(text(driver, "hover-distance"))
        self.assertEqual(shown_id, answer["siteId"])
        site = sites[shown_id]
        self.assertLessEqual(abs(shown_distance - truth[shown_id]), slack(site),
                             f"at {q}: {shown_id} shown at {shown_distance}, exactly {truth[shown_id]}")
        # The point the page draws the line to: on the site, and as near q as the site is.
        closest = answer["closest"]
        self.assertLessEqual(distance(tuple(closest), site), slack(site), f"at {q}: {closest} is off {shown_id}")
        self.assertLessEqual(abs(math.dist(q, closest) - truth[shown_id]), slack(site),
                             f"at {q}: {closest} is {math.dist(q, closest)} away, {shown_id} {truth[shown_id]}")
        # No site is nearer: each is at most its slack farther, as the server measures it.
        nearest = min(truth[id] + slack(s) for id, s in sites.items())
        self.assertLessEqual(shown_distance, nearest,
                             f"at {q}: {shown_id} at {shown_distance}, but a site is at {nearest}")
        return shown_id

    def check_pixel(self, pixel, sites, max_error=None):
        """A SITE_INDEX pixel names a site whose value at the pixel's centre is within the
        frame's bound of the best: a mesh overestimates a site's value by at most max_error
        times its weight."""
        if max_error is None:
            max_error = self.max_error
        c = (pixel["x"], pixel["y"])
        self.assertIn(pixel["id"], sites, pixel)
        weight = lambda s: s.get("multiplicativeWeight", 1)
        best = min(sites.values(), key=lambda s: value(c, s) + slack(s) * weight(s))
        bound = value(c, best) + slack(best) * weight(best) + max_error * weight(best) + 1e-9
        named = sites[pixel["id"]]
        self.assertLessEqual(value(c, named) - slack(named) * weight(named), bound,
                             f"pixel centre {c} names {pixel['id']}; {best['id']} is best at {value(c, best)}")

    def test_hover_highlights_the_exact_nearest_object(self):
        sites = {s["id"]: s for s in mixed_sites(7)}
        version = self.create("mixed", list(sites.values()))
        self.max_error = self.server.ok("GetScene", {"sceneId": "mixed"})["scene"]["maxError"]
        d = self.browser()
        open_scene(d, self.server, "mixed", min_version=version)
        pointer = Pointer(d)
        rnd = random.Random(11)
        tinted = inside = 0
        view = page(d, "window.gvd.view")
        s = pointer.width / (view["maxX"] - view["minX"])
        for k in range(200):
            cx, cy = rnd.uniform(2, pointer.width - 2), rnd.uniform(2, pointer.height - 2)
            answer = pointer.hover(cx, cy)
            # The page's scene point is the pointer's, by the view's own arithmetic.
            at = answer["at"]
            self.assertAlmostEqual(answer["x"], view["minX"] + at[0] / s, delta=1e-9 * 100)
            self.assertAlmostEqual(answer["y"], view["maxY"] - at[1] / s, delta=1e-9 * 100)
            self.assertTrue(answer["found"])
            picked = self.check_hover(d, answer, sites)
            pixel = page(d, f"window.gvd.indexAt({answer['x']}, {answer['y']})")
            if pixel is None:  # outside the scene's window: no pixel
                self.assertFalse(0 < answer["x"] < 100 and 0 < answer["y"] < 100, answer)
                continue
            inside += 1
            self.check_pixel(pixel, sites)
            # The highlight: the region's pixels tinted, the one under the cursor among them.
            alpha = page(d, "document.getElementById('overlay').getContext('2d')"
                            f".getImageData({int(at[0])}, {int(at[1])}, 1, 1).data[3]")
            if pixel["id"] == picked:
                tinted += 1
                self.assertGreater(alpha, 0, f"the region of {picked} is tinted under the cursor")
        self.assertGreater(inside, 50)
        self.assertGreater(tinted, inside / 2)
        self.assertEqual(page(d, "window.gvd.error"), "")
        # A click selects the object nearest to where it was (for the README: a curve selected,
        # a polygon hovered).
        on_curve = bezier_point(points_of(sites["curve2"]["bezier"], "controlPoints"), 0.5)
        pointer.click(*page(d, "window.gvd.toCanvas(%f, %f)" % on_curve))
        wait(d, "document.getElementById('selected-id').textContent === 'curve2'", what="curve2 selected")
        self.assertEqual(text(d, "selected-kind"), "bezier")
        vertex = sites["poly3"]["polygon"]["vertices"][0]
        pointer.hover(*page(d, "window.gvd.toCanvas(%f, %f)" % (vertex["x"] + 0.5, vertex["y"] + 0.5)))
        screenshot(d, "app-selection.png")

    def test_zoomed_past_the_raster_the_picture_is_rendered_at_screen_resolution(self):
        sites = {s["id"]: s for s in mixed_sites(5)}
        version = self.create("zoomed", list(sites.values()))  # pixels of 0.098, finer than the canvas's
        scene_px = 100 / 1024
        max_error = self.server.ok("GetScene", {"sceneId": "zoomed"})["scene"]["maxError"]
        d = self.browser()
        open_scene(d, self.server, "zoomed", min_version=version)
        before = page(d, "window.gvd.indexShape()")
        self.assertAlmostEqual((before["window"]["maxX"] - before["window"]["minX"]) / before["width"], scene_px)
        refreshes = page(d, "window.gvd.refreshes")
        # The wheel, 20 times nearer, about the middle of the canvas.
        d.execute_script("""
const o = document.getElementById('overlay'), r = o.getBoundingClientRect();
o.dispatchEvent(new WheelEvent('wheel', {deltaY: -2000, clientX: r.left + r.width / 2,
                                         clientY: r.top + r.height / 2, cancelable: true}));""")
        wait(d, f"window.gvd.refreshes > {refreshes} && window.gvd.indexShape().width > 0 && "
                "(window.gvd.view.maxX - window.gvd.view.minX) < 50", what="the zoomed picture")
        view = page(d, "window.gvd.view")
        shape = page(d, "window.gvd.indexShape()")
        canvas_px = (view["maxX"] - view["minX"]) / page(d, "document.getElementById('base').width")
        self.assertLess(canvas_px, scene_px / 10)
        w = shape["window"]
        # The picture's pixels are the canvas's, not the scene's stretched.
        self.assertAlmostEqual((w["maxX"] - w["minX"]) / shape["width"], canvas_px, delta=canvas_px * 0.02)
        self.assertAlmostEqual((w["maxY"] - w["minY"]) / shape["height"], canvas_px, delta=canvas_px * 0.02)
        rnd = random.Random(3)
        for _ in range(150):
            x, y = rnd.uniform(w["minX"], w["maxX"]), rnd.uniform(w["minY"], w["maxY"])
            pixel = page(d, f"window.gvd.indexAt({x}, {y})")
            self.check_pixel(pixel, sites, max_error=max_error)

    def test_max_distance_limits_what_is_picked(self):
        sites = {s["id"]: s for s in mixed_sites(8) if s["id"].startswith(("pt", "seg"))}
        version = self.create("limited", list(sites.values()))
        d = self.browser()
        open_scene(d, self.server, "limited", min_version=version)
        field = d.find_element(By.ID, "max-distance")
        field.clear()
        field.send_keys("3", Keys.ENTER)
        pointer = Pointer(d)
        rnd = random.Random(5)
        nothing = 0
        for k in range(40):
            answer = pointer.hover(rnd.uniform(2, pointer.width - 2), rnd.uniform(2, pointer.height - 2))
            if self.check_hover(d, answer, sites, max_distance=3) is None:
                nothing += 1
        self.assertGreater(nothing, 0)
        self.assertLess(nothing, 40)

    def test_dragging_a_point_is_seen_by_another_page(self):
        sites = [{"id": "handle", "point": P(30, 40)}] + [
            {"id": f"p{i}", "point": P(x, y)} for i, (x, y) in enumerate([(10, 10), (50, 50), (90, 90), (10, 90), (90, 10), (25, 60)])]
        version = self.create("drag", sites)
        a, b = self.browser(), self.browser()
        open_scene(a, self.server, "drag", min_version=version)
        open_scene(b, self.server, "drag", min_version=version)
        before = page(b, "window.gvd.frameVersion")
        self.assertEqual(page(b, "window.gvd.indexAt(30, 40).id"), "handle")
        pointer = Pointer(a)
        start = page(a, "window.gvd.toCanvas(30, 40)")
        answer = pointer.hover(*start)
        self.assertEqual(answer["siteId"], "handle")
        end = (start[0] + 200, start[1] - 120)
        pointer.drag(start, end)
        released = time.monotonic()
        # The page sends the move as it goes; the last one is the release point.
        goal = page(a, "window.gvd.toScene(%f, %f)" % end)
        wait(a, "window.gvd.lastWriteVersion > %d" % before, what="the move written")

        def stored():
            p = self.sites("drag")["handle"]["point"]
            return math.hypot(p.get("x", 0) - goal[0], p.get("y", 0) - goal[1])
        deadline = time.monotonic() + 10
        while stored() > 1.5 / pointer.width * 100 and time.monotonic() < deadline:
            time.sleep(0.05)
        self.assertLess(stored(), 1.5 / pointer.width * 100, "the store holds the point where it was dropped")
        written = int(self.server.ok("GetScene", {"sceneId": "drag"})["scene"]["version"])
        # Page b, untouched, follows through WatchScene.
        wait(b, "window.gvd.frameVersion >= %d && window.gvd.indexAt(%f, %f).id === 'handle'" % (written, goal[0], goal[1]),
             timeout=10, what="the second page to show the move")
        seen = time.monotonic() - released
        self.assertNotEqual(page(b, "window.gvd.indexAt(30, 40).id"), "handle")
        print(f"\nsecond page showed the dragged point {seen * 1000:.0f} ms after the release", flush=True)
        with open(os.path.join(ARGS.out, "drag-seen-ms.txt"), "w") as f:
            f.write(f"{seen * 1000:.0f}\n")

    def test_sites_of_every_kind_are_added_and_deleted(self):
        version = self.create("drawn", [{"id": "seed", "point": P(50, 50)}])
        d = self.browser()
        open_scene(d, self.server, "drawn", min_version=version)
        pointer = Pointer(d)
        canvas = lambda x, y: page(d, "window.gvd.toCanvas(%f, %f)" % (x, y))
        scene = lambda c: page(d, "window.gvd.toScene(%f, %f)" % tuple(c))
        plans = {
            "point": [(20, 20)],
            "segment": [(30, 80), (45, 85)],
            "polyline": [(60, 20), (70, 25), (80, 15), (80, 15)],       # the last point again ends it
            "polygon": [(20, 60), (30, 60), (25, 70), (25, 70)],
            "bezier": [(60, 60), (65, 75), (75, 75), (85, 60)],
        }
        expected_points = {"point": 1, "segment": 2, "polyline": 3, "polygon": 3, "bezier": 4}
        for kind, points in plans.items():
            d.find_element(By.CSS_SELECTOR, f"input[name=tool][value={kind}]").click()
            before = page(d, "window.gvd.lastWriteVersion")
            clicks = [canvas(*p) for p in points]
            for c in clicks:
                pointer.click(*c)
            wait(d, f"window.gvd.lastWriteVersion > {before}", what=f"the {kind} written")
            added = [s for id, s in self.sites("drawn").items() if id.startswith(kind + "-")]
            self.assertEqual(len(added), 1, f"one {kind} added: {added}")
            site = added[0]
            key = {"point": None, "segment": None, "polyline": "points", "polygon": "vertices", "bezier": "controlPoints"}[kind]
            got = ([site["point"]] if kind == "point" else [site["segment"]["a"], site["segment"]["b"]] if kind == "segment"
                   else site[kind][key])
            self.assertEqual(len(got), expected_points[kind], site)
            pixel = 1 / page(d, "window.gvd.toCanvas(1, 0)[0] - window.gvd.toCanvas(0, 0)[0]")
            for g, c in zip(got, clicks):  # where clicked, within the pixel the pointer lands on
                want = scene(c)
                self.assertAlmostEqual(g.get("x", 0), want[0], delta=pixel)
                self.assertAlmostEqual(g.get("y", 0), want[1], delta=pixel)
        # Delete: select the polygon by clicking on its edge, then the button.
        d.find_element(By.CSS_SELECTOR, "input[name=tool][value=select]").click()
        pointer.hover(*canvas(25, 60))
        pointer.click(*canvas(25, 60))
        wait(d, "document.getElementById('selected-id').textContent.startsWith('polygon-')", what="the polygon selected")
        before = page(d, "window.gvd.lastWriteVersion")
        d.find_element(By.ID, "delete").click()
        wait(d, f"window.gvd.lastWriteVersion > {before}", what="the deletion written")
        left = self.sites("drawn")
        self.assertFalse([id for id in left if id.startswith("polygon-")], left.keys())
        self.assertEqual(len(left), 5)

    def test_a_3d_scene_is_shown_and_picked_slice_by_slice(self):
        # Points spread through a box of 20 slices: each slice's nearest points differ, and
        # the pick at (x, y) of slice k is of the point (x, y, z_k).
        rnd = random.Random(3)
        points = {f"s{i}": (rnd.uniform(5, 95), rnd.uniform(5, 95), rnd.uniform(0, 40)) for i in range(12)}
        self.server.ok("CreateScene", {"sceneId": "space", "window": {"minX": 0, "minY": 0, "minZ": 0,
                                                                     "maxX": 100, "maxY": 100, "maxZ": 40},
                                       "widthPx": 200, "heightPx": 200, "depthPx": 20})
        version = int(self.server.ok("UpsertSites", {"sceneId": "space", "sites": [
            {"id": k, "point": {"x": x, "y": y, "z": z}} for k, (x, y, z) in points.items()]})["version"])
        d = self.browser()
        open_scene(d, self.server, "space", min_version=version)
        self.assertFalse(page(d, "document.getElementById('z-control').hidden"))
        self.assertEqual(page(d, "window.gvd.slice"), 10)
        self.assertTrue(page(d, "document.querySelector('input[name=tool][value=point]').disabled"))
        pointer = Pointer(d)
        rnd = random.Random(8)
        for k in (10, 0, 19):
            if k != page(d, "window.gvd.slice"):
                page(d, f"(() => {{ const z = document.getElementById('z'); z.value = '{k}'; "
                        "z.dispatchEvent(new Event('input')); return true; })()")
            wait(d, f"window.gvd.slice === {k} && window.gvd.imageSlice === {k}", what=f"slice {k} drawn")
            z = (k + 0.5) * 2
            self.assertEqual(text(d, "z-value"), f"{z:#.4g}")
            for _ in range(12):
                answer = pointer.hover(rnd.uniform(2, pointer.width - 2), rnd.uniform(2, pointer.height - 2))
                q = (answer["x"], answer["y"], z)
                truth = {i: math.dist(q, p) for i, p in points.items()}
                best = min(truth.values())
                self.assertTrue(answer["found"])
                self.assertLessEqual(truth[answer["siteId"]], best + 1e-9, f"slice {k} at {q}: {answer}")
                self.assertAlmostEqual(answer["distance"], truth[answer["siteId"]], delta=1e-9 * 100)
                # The slice's pixel under the pointer names a site nearest within a voxel.
                pixel = page(d, f"window.gvd.indexAt({answer['x']}, {answer['y']})")
                if pixel is not None:
                    c = (pixel["x"], pixel["y"], z)
                    self.assertLessEqual(math.dist(c, points[pixel["id"]]),
                                         min(math.dist(c, p) for p in points.values()) + 1e-6, pixel)
        # A site added elsewhere is seen through the scene's watch: the slice is drawn again.
        later = int(self.server.ok("UpsertSites", {"sceneId": "space", "sites": [
            {"id": "new", "point": {"x": 50, "y": 50, "z": 39}}]})["version"])
        wait(d, f"window.gvd.frameVersion >= {later}", what="the new version drawn")
        self.assertEqual(page(d, "window.gvd.indexAt(50, 50).id"), "new")
        self.assertEqual(page(d, "window.gvd.error"), "")

    def test_bad_requests_get_clear_answers_and_change_nothing(self):
        version = self.create("guarded", [{"id": "a", "point": P(1, 2)}])
        d = self.browser()
        open_scene(d, self.server, "guarded", min_version=version)
        script = """
const [method, body, type] = arguments;
const done = arguments[arguments.length - 1];
fetch('/gvd.v1.VoronoiService/' + method, {method: 'POST', headers: {'Content-Type': type}, body})
  .then(async (r) => done([r.status, await r.text()]), (e) => done([0, String(e)]));
"""
        def post(method, body, type="application/json"):
            status, answer = d.execute_async_script(script, method, body, type)
            return status, json.loads(answer) if answer.startswith("{") else answer
        cases = [
            ("UpsertSites", '{"sceneId": "guarded", "sites": [', 400, "invalid_argument", "UpsertSitesRequest"),
            ("UpsertSites", '{"sceneId": "guarded", "sites": [{"id": "b", "point": {"x": "east"}}]}', 400,
             "invalid_argument", "sites[0].point.x"),
            ("UpsertSites", '{"sceneId": 7}', 400, "invalid_argument", "scene_id"),
            ("UpsertSites", '{"sceneId": "guarded", "sites": [{"id": "", "point": {"x": 1}}]}', 400,
             "invalid_argument", "sites[0].id"),
            ("UpsertSites", json.dumps({"sceneId": "guarded", "sites": [{"id": "big", "polyline": {
                "points": [{"x": i * 1e-3, "y": 1} for i in range(60000)]}}]}), 429, "resource_exhausted",
             "max-message-bytes"),
            ("DropEverything", "{}", 404, "unimplemented", "DropEverything"),
        ]
        for method, body, status, code, named in cases:
            got_status, answer = post(method, body)
            self.assertEqual(got_status, status, f"{method} {body[:60]}: {answer}")
            self.assertEqual(answer["code"], code, answer)
            self.assertIn(named, answer["message"], answer)
        got_status, answer = post("GetScene", '{"sceneId": "guarded"}', "text/plain")
        self.assertEqual(got_status, 415, answer)
        scene = self.server.ok("GetScene", {"sceneId": "guarded"})["scene"]
        self.assertEqual(int(scene["version"]), version, "nothing changed")
        self.assertEqual(list(self.sites("guarded")), ["a"])
        # The page's own error banner, for a call the server refuses.
        field = d.find_element(By.ID, "max-distance")
        field.clear()
        field.send_keys("-1", Keys.ENTER)
        Pointer(d).hover(100, 100)
        self.assertEqual(page(d, "window.gvd.error"), "")  # the app sends no negative limit


class TokenTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.dir = tempfile.mkdtemp(prefix="gvd-tokens-")
        path = os.path.join(cls.dir, "tokens")
        with open(path, "w") as f:
            f.write("reader-token-0123456789 read\nwriter-token-0123456789 write\n")
        cls.server = Server("--tokens", path)

    @classmethod
    def tearDownClass(cls):
        cls.server.stop()
        shutil.rmtree(cls.dir, ignore_errors=True)

    def test_without_a_token_the_app_says_so_and_with_one_it_works(self):
        writer, reader = "writer-token-0123456789", "reader-token-0123456789"
        self.server.ok("CreateScene", {"sceneId": "locked", "window": {"maxX": 10, "maxY": 10},
                                       "widthPx": 256, "heightPx": 256}, token=writer)
        version = int(self.server.ok("UpsertSites", {"sceneId": "locked", "sites": [
            {"id": "a", "point": P(2, 2)}, {"id": "b", "point": P(8, 7)}]}, token=writer)["version"])
        d = browser()
        try:
            d.get(f"{self.server.url}/?scene=locked")
            wait(d, "window.gvd && document.getElementById('error').textContent.includes('unauthenticated')",
                 what="the error shown")
            banner = d.find_element(By.ID, "error")
            self.assertTrue(banner.is_displayed())
            self.assertFalse(page(d, "window.gvd.ready"))
            # A reader sees the scene and hovers; its writes are refused, by name.
            open_scene(d, self.server, "locked", token=reader, min_version=version)
            self.assertFalse(d.find_element(By.ID, "error").is_displayed())
            pointer = Pointer(d)
            answer = pointer.hover(*page(d, "window.gvd.toCanvas(2.2, 2.1)"))
            self.assertEqual(answer["siteId"], "a")
            d.find_element(By.CSS_SELECTOR, "input[name=tool][value=point]").click()
            pointer.click(*page(d, "window.gvd.toCanvas(5, 5)"))
            # The refusal stays in view while the picture goes on refreshing.
            wait(d, "document.getElementById('error').textContent.includes('permission_denied')",
                 what="the refused write shown")
            self.assertTrue(d.find_element(By.ID, "error").is_displayed())
            refreshes = page(d, "window.gvd.refreshes")
            d.find_element(By.ID, "fit").click()  # a refresh, which succeeds
            wait(d, f"window.gvd.refreshes > {refreshes}", what="a refresh")
            self.assertIn("permission_denied", d.find_element(By.ID, "error").text)
            # The token field: a writer's token, kept in the page's storage.
            field = d.find_element(By.ID, "token")
            field.clear()
            field.send_keys(writer, Keys.ENTER)
            wait(d, "window.gvd.ready && !window.gvd.error", what="the scene with the writer's token")
            pointer.click(*page(d, "window.gvd.toCanvas(5, 5)"))
            wait(d, "window.gvd.lastWriteVersion > %d" % version, what="the writer's point")
            sites = self.server.ok("ListSites", {"sceneId": "locked"}, token=reader)["sites"]
            self.assertEqual(len(sites), 3)
            self.assertEqual(page(d, "localStorage.getItem('gvd.token')"), writer)
        finally:
            close(d)


class LatencyTest(unittest.TestCase):
    """The hover round trip on a 100,000-site scene: measured and reported, not asserted."""

    def test_hover_round_trip_on_100k_sites(self):
        server = Server()
        try:
            rnd = random.Random(100000)
            points = [(rnd.uniform(0, 100), rnd.uniform(0, 100)) for _ in range(100000)]
            server.ok("CreateScene", {"sceneId": "big", "window": {"maxX": 100, "maxY": 100},
                                      "widthPx": 1024, "heightPx": 1024})
            version = 0
            for start in range(0, len(points), 25000):
                sites = [{"id": f"s{i}", "point": P(*points[i])} for i in range(start, start + 25000)]
                version = int(server.ok("UpsertSites", {"sceneId": "big", "sites": sites})["version"])
            d = browser()
            try:
                open_scene(d, server, "big", min_version=version)
                pointer = Pointer(d)
                page(d, "window.gvd.latencies.length = 0; window.gvd.parts.length = 0")
                answers = []
                for k in range(300):
                    answers.append(pointer.hover(rnd.uniform(2, pointer.width - 2), rnd.uniform(2, pointer.height - 2)))
                latencies = sorted(page(d, "window.gvd.latencies"))
                parts = page(d, "window.gvd.parts")
                # A sample checked against brute force: the hover answer, and the SITE_INDEX
                # pixel under it (indexes up to 100,000 take all three bytes of a pixel).
                max_error = server.ok("GetScene", {"sceneId": "big"})["scene"]["maxError"]
                for answer in answers[:15]:
                    q = (answer["x"], answer["y"])
                    best = min(math.hypot(q[0] - x, q[1] - y) for x, y in points)
                    self.assertAlmostEqual(answer["distance"], best, delta=1e-9 * 100)
                    pixel = page(d, f"window.gvd.indexAt({q[0]}, {q[1]})")
                    if pixel is None:
                        continue
                    c = (pixel["x"], pixel["y"])
                    best = min(math.hypot(c[0] - x, c[1] - y) for x, y in points)
                    named = points[int(pixel["id"][1:])]
                    self.assertLessEqual(math.hypot(c[0] - named[0], c[1] - named[1]), best + max_error + 1e-9, pixel)
                p50 = latencies[len(latencies) // 2]
                p99 = latencies[min(len(latencies) - 1, int(0.99 * len(latencies)))]
                report = {"sites": len(points), "hovers": len(latencies), "p50_ms": round(p50, 2),
                          "p99_ms": round(p99, 2), "max_ms": round(latencies[-1], 2),
                          "median_parts_ms": {name: round(sorted(p[i] for p in parts)[len(parts) // 2], 2)
                                              for i, name in enumerate(["input_queue", "waiting", "pick", "draw"])},
                          "browser": d.capabilities.get("browserVersion")}
                print(f"\nhover round trip, 100,000 sites: {json.dumps(report)}", flush=True)
                os.makedirs(ARGS.out, exist_ok=True)
                with open(os.path.join(ARGS.out, "hover-latency.json"), "w") as f:
                    json.dump(report, f)
                self.assertEqual(len(latencies), 300)
            finally:
                close(d)
        finally:
            server.stop()


if __name__ == "__main__":
    parser = argparse.ArgumentParser(add_help=False)
    parser.add_argument("--server", required=True)
    parser.add_argument("--out", required=True)
    ARGS, rest = parser.parse_known_args()
    os.makedirs(ARGS.out, exist_ok=True)
    unittest.main(argv=[sys.argv[0]] + rest, verbosity=2)
