"""The tessera Python package against an embedded server: sync, edits as deltas, renders,
and tiles that assemble to the CLI's EXR bit for bit."""

import shutil
import subprocess
from pathlib import Path

import numpy as np
import OpenEXR
import pytest
from pxr import Gf, Usd, UsdGeom

import tessera

ROOT = Path(__file__).resolve().parents[2]
CORNELL = ROOT / "fixtures" / "cornell_box.usda"


@pytest.fixture(scope="module")
def client():
    with tessera.Client() as c:
        yield c


def render(session, width=32, height=32, spp=4, **settings):
    """Every event of a render, and its tiles assembled (the last pass of each rect)."""
    events = list(session.render(width, height, spp=spp, **settings))
    started = events[0]
    assert isinstance(started, tessera.Started), events[0]
    fb = tessera.Framebuffer(started.width, started.height)
    for e in events:
        if isinstance(e, tessera.Tile):
            fb.add(e)
    assert isinstance(events[-1], tessera.Finished), events[-1]
    return events, fb


def test_sync_and_render_the_cornell_box(client):
    session = client.session()
    sent = session.sync_usd(CORNELL)
    kinds = {s["kind"] for s in sent}
    assert {"mesh", "material", "light", "camera"} <= kinds, sent
    assert all(s["dirty"] == ["all"] for s in sent)
    events, fb = render(session, aovs=["albedo"])
    started = events[0]
    assert started.aovs == ["beauty", "albedo"]
    assert [p["effect"] for p in started.plan] == ["lights", "diffuse"]
    beauty = fb.layers["beauty"]
    assert beauty.shape == (32, 32, 4) and beauty.dtype == np.float32
    assert np.isfinite(beauty).all()
    # Inside the frame every pixel sees the box (the outer pixels straddle its open front),
    # and the lit box is well above black.
    assert (beauty[4:-4, 4:-4, 3] == 1.0).all() and beauty[..., :3].mean() > 0.05
    progress = [e for e in events if isinstance(e, tessera.Progress)]
    assert [p.spp for p in progress] == [1, 2, 4]
    assert events[-1].spp == 4 and not events[-1].cancelled


def moved_copy(tmp_path, prim, offset):
    """The Cornell box with one prim translated by `offset`, authored with Pixar's USD."""
    copy = tmp_path / "cornell_moved.usda"
    shutil.copy(CORNELL, copy)
    stage = Usd.Stage.Open(str(copy))
    xform = UsdGeom.Xformable(stage.GetPrimAtPath(prim))
    xform.AddTranslateOp(opSuffix="moved").Set(Gf.Vec3d(*offset))
    stage.Save()
    return copy


def test_resyncing_a_moved_prim_sends_one_transform_delta(client, tmp_path):
    session = client.session()
    sent = session.sync_usd(CORNELL)
    box = "/World/Geo/ShortBox"
    assert any(s["path"] == box for s in sent)
    _, before = render(session)
    assert session.sync_usd(CORNELL) == [], "an unchanged file sends nothing"
    moved = moved_copy(tmp_path, box, (0.0, 0.0, 0.15))
    sent = session.sync_usd(moved)
    assert sent == [{"path": box, "kind": "mesh", "dirty": ["transform"], "chunks": 0}], sent
    _, after = render(session)
    assert not np.array_equal(before.layers["beauty"], after.layers["beauty"]), "the image shows the move"


def test_light_links_without_reexport(client):
    """A light linked to the two boxes alone: the light and every mesh whose membership changed
    go as deltas (meshes with only their categories dirty), the walls lose the light's direct
    light, and unlinking restores the first image bit for bit (the scene is as synced)."""
    session = client.session()
    session.sync_usd(CORNELL)
    light = "/World/Lights/CeilingLight"
    _, base = render(session)
    boxes = ["/World/Geo/ShortBox", "/World/Geo/TallBox"]
    sent = session.set_light_links(light, illuminates=boxes)
    assert {"path": light, "kind": "light", "dirty": ["all"], "chunks": 0} in sent
    assert sorted(s["path"] for s in sent if s["kind"] == "mesh") == boxes
    assert all(s["dirty"] == ["categories"] and s["chunks"] == 0 for s in sent if s["kind"] == "mesh")
    _, linked = render(session)
    # The walls, most of the image, now see the light only by way of the boxes: the median
    # pixel fell from 0.050 to 0.0002 (4 spp); the light itself is still seen.
    b, lk = (img.layers["beauty"][..., :3].mean(axis=2) for img in (base, linked))
    assert np.median(lk) < 0.05 * np.median(b)
    session.set_light_links(light)
    _, unlinked = render(session)
    assert np.array_equal(unlinked.layers["beauty"], base.layers["beauty"])
    with pytest.raises(tessera.TesseraError, match="no light with this path"):
        session.set_light_links("/World/NoSuchLight", illuminates=boxes)


def test_edits_without_reexport(client):
    session = client.session()
    sent = session.sync_usd(CORNELL)
    light = next(s["path"] for s in sent if s["kind"] == "light")
    material = next(s["path"] for s in sent if s["kind"] == "material")
    _, base = render(session)
    assert session.set_light_params(light, intensity=0.0) == [{"path": light, "kind": "light", "dirty": ["all"], "chunks": 0}]
    _, dark = render(session)
    assert dark.layers["beauty"][..., :3].max() < base.layers["beauty"][..., :3].max() * 0.05
    with pytest.raises(tessera.TesseraError, match="no light with this path"):
        session.set_light_params("/World/NoSuchLight", intensity=1.0)
    with pytest.raises(tessera.TesseraError, match="'brightness' is not a light parameter"):
        session.set_light_params(light, brightness=1.0)
    with pytest.raises(tessera.TesseraError, match="no shader 'Nope'"):
        session.set_material_input(material, "Nope", "roughness", 0.5)
    with pytest.raises(tessera.TesseraError, match="render setting max_dept: unknown"):
        render(session, max_dept=3)


def test_a_bad_scene_raises_with_the_file_named(client, tmp_path):
    session = client.session()
    with pytest.raises(tessera.TesseraError, match="malformed.usda"):
        session.sync_usd(ROOT / "fixtures" / "bad" / "malformed.usda")


def exr_channels(path):
    f = OpenEXR.InputFile(str(path))
    header = f.header()
    dw = header["dataWindow"]
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    return {c: np.frombuffer(f.channel(c), dtype=np.float32).reshape(h, w) for c in header["channels"]}


def test_tiles_assemble_to_the_cli_exr_bit_for_bit(client, tmp_path):
    session = client.session()
    session.sync_usd(CORNELL)
    _, fb = render(session, width=40, height=24, spp=8, aovs=["albedo"])
    exr = tmp_path / "cli.exr"
    cmd = ["cargo", "run", "--release", "-q", "-p", "tessera", "--", "render", str(CORNELL), "--res", "40x24", "--spp", "8", "--aov", "albedo", "-o", str(exr)]
    subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True)
    channels = exr_channels(exr)
    beauty = np.stack([channels[c] for c in "RGBA"], axis=-1)
    albedo = np.stack([channels[f"albedo.{c}"] for c in "RGB"], axis=-1)
    assert np.array_equal(beauty.view(np.uint32), fb.layers["beauty"].view(np.uint32))
    assert np.array_equal(albedo.view(np.uint32), fb.layers["albedo"].view(np.uint32))


def test_cancel_stops_a_render(client):
    session = client.session()
    session.sync_usd(CORNELL)
    events = []
    for e in session.render(256, 256, spp=4096):
        events.append(e)
        if isinstance(e, tessera.Progress):
            assert session.cancel()
    finished = events[-1]
    assert isinstance(finished, tessera.Finished) and finished.cancelled, finished
    assert finished.spp < 4096


def test_denoise_lowers_the_error_of_a_16_spp_render(client):
    """`tessera.denoise` (Open Image Denoise) on the package's own tiles: the 16-spp Cornell
    box comes out closer to a 1024-spp render than it went in."""
    session = client.session()
    session.sync_usd(CORNELL)
    _, noisy = render(session, width=96, height=96, spp=16, aovs=["albedo", "normal"])
    _, clean = render(session, width=96, height=96, spp=1024)
    reference = clean.layers["beauty"][..., :3]
    raw = noisy.layers["beauty"]
    denoised = tessera.denoise(raw, noisy.layers["albedo"], noisy.layers["normal"])
    assert denoised.shape == (96, 96, 3) and np.isfinite(denoised).all()
    rel = lambda img: float(((img - reference) ** 2 / (reference**2 + 0.01)).mean())  # noqa: E731
    assert rel(denoised) < 0.5 * rel(raw[..., :3]), (rel(denoised), rel(raw[..., :3]))
    with pytest.raises(tessera.TesseraError, match="albedo holds"):
        tessera.denoise(raw, noisy.layers["albedo"][:10], noisy.layers["normal"])


def test_closing_sessions_frees_their_places_on_the_server():
    """The server holds at most 64 sessions (its registry's limit); one never closed lingers
    until the idle timeout (ten minutes). A client that closes each session, as the Blender
    add-on does after every render, opens as many as it likes; closing twice does nothing."""
    with tessera.Client() as c:
        for _ in range(70):
            with c.session() as s:
                s.close()
        held = [c.session() for _ in range(64)]
        with pytest.raises(tessera.TesseraError, match="64 sessions are open"):
            c.session()
        held[0].close()
        c.session().close()
