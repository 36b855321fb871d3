"""The fuzz suite's table: every input omnidev reads, the command that reads it, the bad values.

A new command or input is one entry here:

- :data:`FILE_TARGETS`: a file format, the seed it is made from, the command line
  that reads it (``{f}`` = the malformed file, ``{s}`` = the seeds folder);
- :data:`OPTION_TARGETS`: a command line with one option or URI, and the values that
  must be refused (or may be accepted) there;
- :func:`config_key_cases`: every key of the daemon configuration with wrong types,
  non-finite and out-of-range values, through ``omnidev daemon --check``.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass, field

from tests.fuzz.harness import Case
from tests.fuzz.mutate import Expect, key_variants, variants
from tests.fuzz.seeds import Seeds

UNWARP_OUT = ["--view", "panorama:64x16", "-o", "out.png"]
RECORD = ["--sink", "record", "--sink-option", "path=rec.jsonl"]


@dataclass(frozen=True)
class FileTarget:
    command: str
    what: str  # the input format
    seed: str  # file name in the seeds folder
    argv: tuple[str, ...]  # {f}: the malformed file, {s}: the seeds folder
    text: bool = True
    numbers: int = 3
    numbers_refuse: bool = True  # a NaN/inf in any number of the seed must be refused
    timeout: float = 60.0  # wall time: generous, the test machine may be loaded
    keys: bool = False  # also every ``key: number`` of a YAML file set to NaN, -1 and 1e9

    @property
    def ext(self) -> str:
        name = self.seed.lower()
        return ".yml" if name.endswith(".yml.gz") else "." + name.rsplit(".", 1)[-1]

    @property
    def file_name(self) -> str:
        return "in" + (".yml.gz" if self.seed.endswith(".gz") else self.ext)


FILE_TARGETS: tuple[FileTarget, ...] = (
    FileTarget(
        "calibrate pano-table", "landmark CSV", "landmarks.csv",
        ("calibrate", "pano-table", "{f}", "--mirror-center", "0.3,-0.2,1.2", "--image-center",
         "322.9,317.4", "--image-size", "640x640", "--table-size", "48x24", "-o", "out.yml"),
    ),
    FileTarget(
        "unwarp", "rig TOML", "rig.toml",
        ("unwarp", "--rig", "{f}", *UNWARP_OUT),
        numbers=0,
    ),
    FileTarget("daemon --check", "daemon config TOML", "daemon.toml",
               ("daemon", "--config", "{f}", "--check")),
    FileTarget("daemon --check", "daemon streams TOML", "streams.toml",
               ("daemon", "--config", "{f}", "--check")),
    FileTarget("mouse", "layout JSON", "layout.json",
               ("mouse", "{s}/mouse.avi", "--layout", "{f}", *RECORD)),
    FileTarget("mouse", "layout TOML", "layout.toml",
               ("mouse", "{s}/mouse.avi", "--layout", "{f}", *RECORD)),
    FileTarget(
        "calibrate nonsvp-hyper", "nonsvp point CSV", "points.csv",
        ("calibrate", "nonsvp-hyper", "--points", "{f}", "--mirror", "28.3646,32.0661,29",
         "--lens", "2.9,3.2,2.4", "--size", "640x480", "-o", "out.yml"),
    ),
    FileTarget("replay", "replay JSONL", "rec.jsonl",
               ("replay", "{f}", "--sink", "record", "--sink-option", "path=out.jsonl", "--fast"),
               numbers_refuse=False),
    FileTarget("unwarp", "pano-table YAML", "cam.yml",
               ("unwarp", "{s}/omni.png", "--camera", "{f}", *UNWARP_OUT), numbers=4,
               numbers_refuse=False, keys=True),
    FileTarget("unwarp", "pano-table YAML format 1", "cam_v1.yml",
               ("unwarp", "{s}/omni.png", "--camera", "{f}", *UNWARP_OUT), numbers=2,
               numbers_refuse=False, keys=True),
    FileTarget("unwarp", "generalized pano-table YAML", "cam_general.yml",
               ("unwarp", "{s}/omni.png", "--camera", "{f}", *UNWARP_OUT), numbers=2,
               numbers_refuse=False, keys=True),
    FileTarget("unwarp", "generalized pano-table YAML, unified radial", "cam_unified.yml",
               ("unwarp", "{s}/omni.png", "--camera", "{f}", *UNWARP_OUT), numbers=2,
               numbers_refuse=False, keys=True),
    FileTarget("calibrate pano-table --model general", "landmark CSV with groups", "boards.csv",
               ("calibrate", "pano-table", "{f}", "--model", "general", "--mirror-center",
                "0.3,-0.2,1.2", "--image-center", "320,320", "--image-size", "640x640",
                "--table-size", "48x24", "-o", "out.yml"), numbers_refuse=False),
    FileTarget("landmarks board", "board rig TOML", "boards.toml",
               ("landmarks", "board", "{s}/shot.png", "--boards", "{f}", "-o", "out.csv"),
               numbers=4, timeout=120.0),
    FileTarget("landmarks board", "omni-image PNG", "shot.png",
               ("landmarks", "board", "{f}", "--boards", "{s}/boards.toml", "-o", "out.csv"),
               text=False, timeout=120.0),
    FileTarget("unwarp", "pano-table YAML .gz", "cam.yml.gz",
               ("unwarp", "{s}/omni.png", "--camera", "{f}", *UNWARP_OUT), text=False),
    FileTarget("unwarp", "fisheye YAML", "fish.yml",
               ("unwarp", "{s}/fish.png", "--camera", "{f}", "--view",
                "perspective:64x48", "-o", "out.png"), numbers=4, numbers_refuse=False, keys=True),
    FileTarget("unwarp", "nonsvp-hyper YAML", "nonsvp.yml",
               ("unwarp", "{s}/nonsvp.png", "--camera", "{f}", "--view",
                "top:64x48,x=4000,y=4000,z=-2000", "-o", "out.png"), numbers=4,
               numbers_refuse=False, keys=True),
    FileTarget("laser", "screen calibration YAML", "screen.yml",
               ("laser", "{s}/laser.avi", "--calibration", "{f}", *RECORD), numbers=4,
               numbers_refuse=False, keys=True),
    FileTarget("calibrate import", "OCamCalib calib_results.txt", "calib_results.txt",
               ("calibrate", "import", "{f}", "--format", "ocamcalib", "-o", "out.yml")),
    FileTarget("calibrate import", "Kalibr camchain YAML", "kalibr.yaml",
               ("calibrate", "import", "{f}", "--format", "kalibr", "-o", "out.yml")),
    FileTarget("calibrate import", "basalt JSON", "basalt.json",
               ("calibrate", "import", "{f}", "--format", "basalt", "-o", "out.yml"),
               numbers=4),
    FileTarget("calibrate import", "py-OCamCalib JSON", "pyocam.json",
               ("calibrate", "import", "{f}", "--format", "pyocamcalib", "--image-size",
                "1088x760", "-o", "out.yml"), numbers_refuse=False),
    FileTarget("calibrate import", "OpenCV K/D YAML", "opencv.yml",
               ("calibrate", "import", "{f}", "--format", "opencv", "--image-size", "512x512",
                "-o", "out.yml")),
    FileTarget("unwarp", "input image PNG", "omni.png",
               ("unwarp", "{f}", "--camera", "{s}/cam.yml.gz", *UNWARP_OUT), text=False),
    FileTarget("unwarp", "input image JPEG", "omni.jpg",
               ("unwarp", "{f}", "--camera", "{s}/cam.yml.gz", *UNWARP_OUT), text=False),
    FileTarget("unwarp", "input video AVI", "omni.avi",
               ("unwarp", "{f}", "--camera", "{s}/cam.yml.gz", "--view", "panorama:64x16",
                "-o", "out.avi"), text=False),
    FileTarget("calibrate pano-table", "omni-image PNG", "omni.png",
               ("calibrate", "pano-table", "{s}/landmarks.csv", "--mirror-center",
                "0.3,-0.2,1.2", "--image", "{f}", "--image-center", "322.9,317.4",
                "--table-size", "48x24", "-o", "out.yml"), text=False),
    FileTarget("calibrate screen", "captured white PNG", "white.png",
               ("calibrate", "screen", "--white", "{f}", "--black", "{s}/black.png", "--dots",
                "{s}/dots.png", "-o", "out.yml"), text=False),
    FileTarget("calibrate fisheye", "chessboard PNG", "board.png",
               ("calibrate", "fisheye", "{f}", *(f"{{s}}/cb/view0{k}.png" for k in range(1, 6)),
                "--pattern", "chessboard:7x5,40", "--holdout", "0", "-o", "out.yml"),
               text=False),
)  # fmt: skip


def seed_cases(seeds: Seeds, targets: tuple[FileTarget, ...] = FILE_TARGETS) -> list[Case]:
    """Each file target's command on its unmodified seed: it must exit 0 (what "seed" means)."""
    cases = []
    for t in targets:
        argv = [
            a.replace("{f}", str(seeds[t.seed])).replace("{s}", str(seeds.root)) for a in t.argv
        ]
        cases.append(
            Case(t.command, f"{t.what}: the seed as it is", argv, expect="any", timeout=t.timeout)
        )
    return cases


def file_cases(seeds: Seeds) -> Iterator[Case]:
    """Every malformed variant of every file target."""
    for t in FILE_TARGETS:
        seed = seeds.text(t.seed)
        for k, v in enumerate(
            variants(seed, t.ext, text=t.text, numbers=t.numbers, numbers_refuse=t.numbers_refuse)
        ):
            argv = [a.replace("{f}", t.file_name).replace("{s}", str(seeds.root)) for a in t.argv]
            # the rig's calibration and source are relative to the rig: give them beside it
            files = {t.file_name: v.spec}
            if t.seed == "rig.toml":
                files["cam.yml.gz"] = seeds.text("cam.yml.gz")
                files["omni.png"] = seeds.text("omni.png")
            yield Case(
                t.command,
                f"{t.what}: {v.what} (#{k})",
                argv,
                files,
                expect=v.expect,
                timeout=t.timeout,
            )
        if t.keys:
            argv = [a.replace("{f}", t.file_name).replace("{s}", str(seeds.root)) for a in t.argv]
            for v in key_variants(seed):
                yield Case(t.command, f"{t.what}: {v.what}", argv, {t.file_name: v.spec},
                           expect=v.expect, timeout=t.timeout)  # fmt: skip


@dataclass(frozen=True)
class OptionTarget:
    command: str
    argv: tuple[str, ...]  # {v}: the value; {s}: the seeds folder
    refuse: tuple[str, ...]
    accept: tuple[str, ...] = ()  # values that may be accepted (still no traceback etc.)
    files: dict[str, str] = field(default_factory=dict)  # case file -> seed name


NONFINITE = ("nan", "inf", "-inf", "NaN", "1e400")
NUMBERS_BAD = (*NONFINITE, "abc", "")

OPTION_TARGETS: tuple[OptionTarget, ...] = (
    OptionTarget("unwarp", ("unwarp", "{s}/omni.avi", "--camera", "{s}/cam.yml.gz", "--view",
                            "panorama:64x16", "-o", "out.avi", "--fps", "{v}"),
                 (*NUMBERS_BAD, "0", "-1", "1e308", "-1e308", "100000"), ("30", "0.5")),
    OptionTarget("unwarp", ("unwarp", "{s}/omni.avi", "--camera", "{s}/cam.yml.gz", "--view",
                            "panorama:64x16", "-o", "out.avi", "--frames", "{v}"),
                 ("0", "-1", "1.5", "abc", "", "nan"), ("1", "99999999999999999999")),
    OptionTarget("unwarp", ("unwarp", "{s}/omni.png", "--camera", "{s}/cam.yml.gz", "--view",
                            "{v}", "-o", "out.png"),
                 ("panorama:32768x32768", "perspective:20000x20000", "equirect:32768x16384",
                  "top:30000x30000,x=4,y=4,z=-1", "plane:25000x25000,d=2,w=3,z=-1:1",
                  "cylinder:32768x9000,d=2,z=-1:1", "panorama:0x0", "panorama:-5x5",
                  "panorama:64x16,elev=nan:10", "panorama:64x16,elev=10:-60",
                  "panorama:64x16,elev=-1e308:1e308", "panorama:64x16,span=0",
                  "panorama:64x16,span=inf", "panorama:64x16,start=1e308",
                  "perspective:64x48,fov=0", "perspective:64x48,fov=180",
                  "perspective:64x48,fov=-30", "perspective:64x48,fov=1e308",
                  "perspective:64x48,pan=nan", "plane:64x48,d=0,w=0,z=0:0",
                  "plane:64x48,d=-2,w=3,z=-1:1", "plane:64x48,d=2,w=-3,z=1:-1",
                  "top:64x48,x=inf,y=4,z=-1", "top:64x48,x=4,y=4,z=0",
                  "cylinder:64x48,d=0,z=-1:1", "equirect:64x32,lon=10:10",
                  "equirect:64x32,lat=-100:100", "panorama:64x16,ccw=2", "panorama",
                  "panorama:", "panorama:64x16,,=", "blob:10x10", ":", "x" * 5000,
                  "panorama:99999999999999999999x1",
                  "plane:64x48,c=2:0:0,n=0:0:0,w=1,h=1", "plane:64x48,c=2:0:0,n=1:0:0,w=1,h=1,d=2",
                  "plane:25000x25000,c=2:0:0,n=1:0:0,w=1,h=1",
                  "plane:64x48,c=nan:0:0,n=1:0:0,w=1,h=1",
                  "plane:64x48,c=2:0:0,n=1:0:0,w=-1,h=1", "plane:64x48,c=2:0,n=1:0:0,w=1,h=1",
                  "plane:64x48,c=0:0:0,n=1:0:0,w=1,h=1", "plane:64x48,c=2:0:0,n=1:0:0,w=1"),
                 ("plane:64x48,c=2:0:0,n=1:0:0,w=1,h=1", "plane:64x48,c=0:0:-1,n=0:0:1,w=2,h=2",
                  "perspective:64x48,tilt=1e308",
                  "perspective:64x48,roll=-720", "panorama:64x16,start=-360,span=360")),
    OptionTarget("unwarp", ("unwarp", "{v}", "--camera", "{s}/cam.yml.gz", *UNWARP_OUT),
                 ("video:{s}/omni.avi?rate=inf", "video:{s}/omni.avi?rate=nan",
                  "video:{s}/omni.avi?rate=-1", "video:{s}/omni.avi?rate=0",
                  "video:{s}/omni.avi?rate=1e308", "video:{s}/omni.avi?rate=abc",
                  "video:{s}/omni.avi?loop=2", "video:{s}/omni.avi?bogus=1",
                  "video:{s}/nothere.avi", "video:/dev/zero", "video:{s}", "images:{s}/none*.png",
                  "images:/dev/zero", "images:{s}/omni.png?x=1", "v4l2:/dev/nonexistent",
                  "v4l2:/dev/zero", "v4l2:/dev/video0?width=-1", "v4l2:/dev/video0?fps=inf",
                  "v4l2:/dev/video0?fps=nan", "v4l2:/dev/video0?fourcc=ABCDE",
                  "v4l2:/dev/video0?buffers=1e9", "usb:zzzz:yyyy", "usb:046d:0825", "usb:",
                  "mystery:thing", "", "/dev/zero", "{s}/nothere.png", "video:"),
                 ("video:{s}/omni.avi?rate=30&loop=0",)),
    OptionTarget("unwarp", ("unwarp", "{s}/omni.png", "--camera", "{s}/cam.yml.gz",
                            "--camera-option", "{v}", *UNWARP_OUT),
                 ("lookup=cubic", "bogus=1", "=", "lookup", "x" * 3000)),
    OptionTarget("unwarp", ("unwarp", "{s}/omni.png", "--camera", "{s}/cam.yml.gz",
                            "--view", "panorama:64x16", "-o", "{v}"),
                 ("out.xyz", "out", "{s}", "/dev/zero", "nodir/out.png", "", ".png",
                  "/proc/version"), ("out.PNG", "o.avi")),
    OptionTarget("calibrate pano-table",
                 ("calibrate", "pano-table", "{s}/landmarks.csv", "--mirror-center", "{v}",
                  "--image-center", "322.9,317.4", "--image-size", "640x640",
                  "--table-size", "48x24", "-o", "out.yml"),
                 ("nan,0,1", "inf,0,1", "1e308,1e308,1e308", "0,0", "0,0,1,1", "a,b,c", "",
                  "1e400,0,0"), ("0.3,-0.2,1.2", "-0.3,0.2,1.2", "-1e3,0,1")),
    OptionTarget("calibrate pano-table",
                 ("calibrate", "pano-table", "{s}/landmarks.csv", "--mirror-center",
                  "0.3,-0.2,1.2", "--image-center", "{v}", "--image-size", "640x640",
                  "--table-size", "48x24", "-o", "out.yml"),
                 ("nan,320", "inf,inf", "320", "1e308,1e308", "detect", "-1e9,320"),
                 ("-5,320", "700,700")),
    OptionTarget("calibrate pano-table",
                 ("calibrate", "pano-table", "{s}/landmarks.csv", "--mirror-center",
                  "0.3,-0.2,1.2", "--image-center", "322.9,317.4", "--image-size", "{v}",
                  "--table-size", "48x24", "-o", "out.yml"),
                 ("100000x100000", "0x0", "-640x640", "640", "640x", "x", "1e3x1e3",
                  "99999999999999999999x2"), ("64x64",)),
    OptionTarget("calibrate pano-table",
                 ("calibrate", "pano-table", "{s}/landmarks.csv", "--mirror-center",
                  "0.3,-0.2,1.2", "--image-center", "322.9,317.4", "--image-size", "640x640",
                  "--table-size", "{v}", "-o", "out.yml"),
                 ("32768x32768", "100000x10", "0x10", "-4x4", "1x1", "axb"), ("16x8",)),
    OptionTarget("calibrate pano-table",
                 ("calibrate", "pano-table", "{s}/landmarks.csv", "--mirror-center",
                  "0.3,-0.2,1.2", "--image-center", "322.9,317.4", "--image-size", "640x640",
                  "--table-size", "48x24", "--elevation-range", "{v}", "-o", "out.yml"),
                 ("10,-50", "nan,10", "-50,inf", "-1e308,1e308", "-50", "5,5", "-95,10",
                  "-50,95"), ("-50,10", "-60,-10")),
    OptionTarget("calibrate pano-table",
                 ("calibrate", "pano-table", "{s}/landmarks.csv", "--mirror-center",
                  "0.3,-0.2,1.2", "--image-center", "322.9,317.4", "--image-size", "640x640",
                  "--table-size", "48x24", "--cutoff-radius", "{v}", "-o", "out.yml"),
                 ("nan", "inf", "-1", "1e308", "100000"), ("0", "20")),
    OptionTarget("calibrate pano-table",
                 ("calibrate", "pano-table", "{s}/landmarks.csv", "--mirror-center",
                  "0.3,-0.2,1.2", "--image-center", "322.9,317.4", "--image-size", "640x640",
                  "--table-size", "48x24", "--model", "{v}", "-o", "out.yml"),
                 ("bogus", "", "General"), ("general", "dissertation")),
    OptionTarget("calibrate pano-table",
                 ("calibrate", "pano-table", "{s}/landmarks.csv", "--mirror-center",
                  "0.3,-0.2,1.2", "--image-center", "322.9,317.4", "--image-size", "640x640",
                  "--table-size", "48x24", "--max-residual", "{v}", "-o", "out.yml"),
                 ("nan", "inf", "-1", "abc", "1e-9"), ("0", "5")),
    OptionTarget("calibrate pano-table",
                 ("calibrate", "pano-table", "{s}/landmarks.csv", "--mirror-center",
                  "0.3,-0.2,1.2", "--image", "{s}/omni.png", "--center-kind", "{v}", "-o",
                  "out.yml"),
                 ("bogus", ""), ("fisheye", "mirror")),
    OptionTarget("landmarks board",
                 ("landmarks", "board", "{s}/shot.png", "--boards", "{s}/boards.toml",
                  "--min-corners", "{v}", "-o", "out.csv"),
                 ("nan", "-1", "abc", "100000"), ("4",)),
    OptionTarget("landmarks board",
                 ("landmarks", "board", "{v}", "--boards", "{s}/boards.toml", "-o", "out.csv"),
                 ("{s}/nothere.png", "{s}", "/dev/zero", "", "{s}/boards.toml")),
    OptionTarget("landmarks board",
                 ("landmarks", "board", "{s}/shot.png", "--boards", "{s}/boards.toml", "-o",
                  "{v}"),
                 ("{s}", "nodir/out.csv", "", "/dev/zero")),
    OptionTarget("calibrate fisheye",
                 ("calibrate", "fisheye", *(f"{{s}}/cb/view0{k}.png" for k in range(6)),
                  "--pattern", "chessboard:7x5,40", "--holdout", "0", "--model", "{v}", "-o",
                  "out.yml"),
                 ("bogus", ""), ("scaramuzza", "mei")),
    OptionTarget("calibrate import",
                 ("calibrate", "import", "{s}/pyocam.json", "--image-size", "{v}", "-o",
                  "out.yml"),
                 ("100000x100000", "0x0", "-5x5", "abc"), ("1088x760",)),
    OptionTarget("calibrate import",
                 ("calibrate", "import", "{s}/kalibr.yaml", "--max-angle-deg", "{v}", "-o",
                  "out.yml"),
                 ("nan", "inf", "-10", "0", "1e308", "abc"), ("95",)),
    OptionTarget("calibrate import",
                 ("calibrate", "import", "{s}/kalibr.yaml", "--camera", "{v}", "-o", "out.yml"),
                 ("cam7", "-1", "99999999999999999999", ""), ("cam0", "0")),
    OptionTarget("calibrate screen",
                 ("calibrate", "screen", "--white", "{s}/white.png", "--black", "{s}/black.png",
                  "--dots", "{s}/dots.png", "--n", "{v}", "-o", "out.yml"),
                 ("0", "1", "-3", "100000", "abc")),
    OptionTarget("calibrate screen",
                 ("calibrate", "screen", "--white", "{s}/white.png", "--black", "{s}/black.png",
                  "--dots", "{s}/dots.png", "--screen", "{v}", "-o", "out.yml"),
                 ("0x0", "100000x100000", "-1920x1080", "abc")),
    OptionTarget("calibrate screen",
                 ("calibrate", "screen", "--write-patterns", "pats", "--screen", "{v}"),
                 ("100000x100000", "40000x40000", "0x0"), ("64x48",)),
    OptionTarget("calibrate screen",
                 ("calibrate", "screen", "--white", "{s}/white.png", "--black", "{s}/black.png",
                  "--dots", "{s}/dots.png", "--method", "{v}", "-o", "out.yml"),
                 ("bogus", "")),
    OptionTarget("calibrate nonsvp-hyper",
                 ("calibrate", "nonsvp-hyper", "--points", "{s}/points.csv", "--mirror", "{v}",
                  "--lens", "2.9,3.2,2.4", "--size", "640x480", "-o", "out.yml"),
                 ("nan,32,29", "28,inf,29", "-28,32,29", "0,0,0", "1e308,1e308,1e308", "28,32",
                  "28,32,-29")),
    OptionTarget("calibrate nonsvp-hyper",
                 ("calibrate", "nonsvp-hyper", "--points", "{s}/points.csv", "--mirror",
                  "28.3646,32.0661,29", "--lens", "{v}", "--size", "640x480", "-o", "out.yml"),
                 ("nan,3.2,2.4", "0,3.2,2.4", "-2.9,3.2,2.4", "2.9,0,0", "1e308,3.2,2.4")),
    OptionTarget("calibrate nonsvp-hyper",
                 ("calibrate", "nonsvp-hyper", "--points", "{s}/points.csv", "--mirror",
                  "28.3646,32.0661,29", "--lens", "2.9,3.2,2.4", "--size", "{v}", "-o",
                  "out.yml"),
                 ("0x0", "100000x100000", "-640x480")),
    OptionTarget("nonsvp-ring", ("nonsvp-ring", "ring", "--dpi", "72", "--mirror-radius-mm", "{v}"),
                 ("nan", "inf", "-29", "0", "1e308", "1e6"), ("29",)),
    OptionTarget("nonsvp-ring", ("nonsvp-ring", "ring", "--mirror-radius-mm", "29", "--dpi",
                                 "{v}"),
                 ("nan", "inf", "0", "-300", "1e308", "100000")),
    OptionTarget("mouse-landmarks",
                 ("mouse-landmarks", "sheet", "--dpi", "72", "--screen-mm", "{v}"),
                 ("nanx300", "infx300", "0x0", "-530x300", "1e308x1e308", "530", "100000x100000"),
                 ("530x300",)),
    OptionTarget("mouse-landmarks", ("mouse-landmarks", "sheet", "--dpi", "72",
                                     "--screen-mm", "300x200", "--circle-mm", "{v}"),
                 ("nan", "inf", "0", "-20", "1e308", "500")),
    OptionTarget("mouse-landmarks", ("mouse-landmarks", "sheet", "--dpi", "72",
                                     "--screen-mm", "300x200", "--margin-mm", "{v}"),
                 ("nanx25", "infx25", "-25x25", "1e308x1e308", "25")),
    OptionTarget("mouse", ("mouse", "{s}/mouse.avi", "--layout", "{s}/layout.json", *RECORD,
                           "--fov-deg", "{v}"),
                 ("nan", "inf", "0", "-60", "180", "1e308", "abc")),
    OptionTarget("mouse", ("mouse", "{s}/mouse.avi", "--layout", "{s}/layout.json", *RECORD,
                           "--dwell", "--dwell-s", "{v}"),
                 ("nan", "inf", "0", "-1", "1e308")),
    OptionTarget("mouse", ("mouse", "{s}/mouse.avi", "--layout", "{s}/layout.json", *RECORD,
                           "--dwell", "--dwell-radius-px", "{v}"),
                 ("nan", "inf", "0", "-1", "1e308")),
    OptionTarget("mouse", ("mouse", "{s}/mouse.avi", "--layout", "{s}/layout.json", *RECORD,
                           "--screen", "{v}"),
                 ("0x0+0+0", "-1920x1080+0+0", "1920x1080+-5+0", "abc", "", "99999999x9+0+0")),
    OptionTarget("mouse", ("mouse", "{s}/mouse.avi", "--layout", "{s}/layout.json", *RECORD,
                           "--buttons", "{v}"),
                 ("evdev:/dev/input/event99?KEY_SPACE=left", "evdev:/dev/zero?KEY_SPACE=left",
                  "hid:zzzz:0001?key.0x4e=left", "bogus:thing", "evdev:", "hid:046d:c52b")),
    OptionTarget("mouse", ("mouse", "{s}/mouse.avi", "--layout", "{s}/layout.json",
                           "--sink", "{v}"),
                 ("recrd", "", "uinput-x"), ("record",)),
    OptionTarget("mouse", ("mouse", "{s}/mouse.avi", "--layout", "{s}/layout.json",
                           "--sink", "record", "--sink-option", "{v}"),
                 ("path=", "path=/nodir/x.jsonl", "path={s}", "bogus=1", "nokey", "=x")),
    OptionTarget("laser", ("laser", "{s}/laser.avi", "--calibration", "{s}/screen.yml", *RECORD,
                           "--screen", "{v}"),
                 ("0x0+0+0", "abc"), ("640x480+0+0",)),
    OptionTarget("laser", ("laser", "{s}/laser.avi", "--calibration", "{s}/screen.yml",
                           "--sink", "{v}"),
                 ("recrd", "hidg", "")),
    OptionTarget("replay", ("replay", "{s}/rec.jsonl", "--sink", "record", "--sink-option",
                            "path=out.jsonl", "--screen", "{v}"),
                 ("0x0+0+0", "-5x5+0+0", "abc", "", "1e9x1e9+0+0")),
    OptionTarget("replay", ("replay", "{s}/rec.jsonl", "--sink", "{v}", "--fast"),
                 ("recrd", "", "hidg", "record")),
    OptionTarget("ctl", ("ctl", "status", "--socket", "nosock", "--timeout", "{v}"),
                 ("-1", "nan", "inf", "0", "1e308", "-inf", "abc")),
    OptionTarget("ctl", ("ctl", "status", "--socket", "{v}"),
                 ("nosock", "/dev/zero", "{s}", "", "x" * 200)),
    OptionTarget("daemon --check", ("daemon", "--config", "{v}", "--check"),
                 ("nothere.toml", "{s}", "/dev/zero", "", "{s}/landmarks.csv")),
    OptionTarget("bench", ("bench", "{v}"), ("nosuchbench", "", "../unwarp")),
    OptionTarget("sim omni", ("sim", "omni", "simout", "--size", "{v}"),
                 ("0", "-5", "100000", "nan", "abc")),
    OptionTarget("sim omni", ("sim", "omni", "simout", "--size", "64", "--frames", "{v}"),
                 ("0", "-1", "99999999999", "abc")),
    OptionTarget("sim omni", ("sim", "omni", "simout", "--size", "64", "--frames", "1",
                              "--fps", "{v}"),
                 ("nan", "inf", "0", "-1", "1e308")),
    OptionTarget("sim blob", ("sim", "blob", "simout", "--size", "{v}"),
                 ("0x0", "100000x100000", "-5x5", "abc")),
    OptionTarget("sim blob", ("sim", "blob", "simout", "--size", "64x48", "--frames", "{v}"),
                 ("0", "-1", "99999999999")),
    OptionTarget("sim blob", ("sim", "blob", "simout", "--size", "64x48", "--frames", "2",
                              "--fps", "{v}"),
                 ("nan", "inf", "0", "-1", "1e308")),
    OptionTarget("sim mouse", ("sim", "mouse", "simout", "--size", "{v}"),
                 ("0x0", "100000x100000", "-5x5")),
    OptionTarget("sim mouse", ("sim", "mouse", "simout", "--frames", "{v}"),
                 ("0", "-1", "99999999999")),
    OptionTarget("sim screen", ("sim", "screen", "simout", "--size", "{v}"),
                 ("0x0", "100000x100000", "-5x5")),
    OptionTarget("sim screen", ("sim", "screen", "simout", "--k1", "{v}"),
                 ("nan", "inf", "1e308", "-1e308")),
    OptionTarget("sim screen", ("sim", "screen", "simout", "--n", "{v}"),
                 ("0", "1", "-3", "100000")),
    OptionTarget("sim nonsvp", ("sim", "nonsvp", "simout", "--size", "{v}"),
                 ("0x0", "100000x100000", "-5x5")),
    OptionTarget("sim nonsvp", ("sim", "nonsvp", "simout", "--T", "{v}"),
                 ("nan,0,88", "inf,0,88", "1e308,0,0", "0,0")),
    OptionTarget("sim nonsvp", ("sim", "nonsvp", "simout", "--supersample", "{v}"),
                 ("0", "-1", "100000")),
    OptionTarget("sim chessboard", ("sim", "chessboard", "simout", "--views", "{v}"),
                 ("0", "-1", "100000")),
    OptionTarget("sim chessboard", ("sim", "chessboard", "simout", "--size", "{v}"),
                 ("0x0", "100000x100000")),
    OptionTarget("sim chessboard", ("sim", "chessboard", "simout", "--pattern", "{v}"),
                 ("chessboard:0x0,30", "chessboard:9x6,nan", "chessboard:9x6,-30", "bogus",
                  "chessboard:100000x100000,30")),
    # outputs (omnidev.outputs: file, y4m, raw, v4l2) and the threaded pipeline
    OptionTarget("unwarp -o", ("unwarp", "{s}/omni.avi", "--camera", "{s}/cam.yml.gz", "--view",
                               "panorama:64x16", "--frames", "2", "-o", "{v}"),
                 ("out.mp4?crf=nan", "out.mp4?crf=-1", "out.mp4?crf=1e308",
                  "out.mp4?preset=slowest", "out.mp4?codec=bogus",
                  "out.avi?q=0", "out.avi?q=nan", "out.mp4?bogus=1",
                  "out.xyz", "out", "{s}", "nodir/out.mp4", "/dev/zero", "/proc/version",
                  "raw:-?format=bogus", "raw:out.raw?format=", "y4m:nodir/out.y4m", "y4m:{s}",
                  "v4l2:/dev/null", "v4l2:/dev/zero", "v4l2:/dev/video99", "v4l2:",
                  "v4l2:{s}/omni.avi", "v4l2:/dev/null?format=bogus", "bogus:thing",
                  "file:", "file:out.mp4?crf=", "out.png"),
                 ("out.mp4", "out.mp4?crf=30&preset=ultrafast", "out.avi?q=5", "y4m:out.y4m",
                  "raw:out.raw?format=gray", "file:out.mkv")),
    OptionTarget("unwarp", ("unwarp", "{s}/omni.avi", "--camera", "{s}/cam.yml.gz", "--view",
                            "panorama:64x16", "--frames", "2", "-o", "out.avi", "--threads", "{v}"),
                 ("0", "-1", "abc", "nan", "99999999999999999999"), ("1", "2")),
    OptionTarget("unwarp", ("unwarp", "{s}/omni.avi", "--camera", "{s}/cam.yml.gz", "--view",
                            "panorama:64x16", "-o", "out.avi", "--view", "panorama:64x16",
                            "-o", "{v}"),
                 ("out.avi", "./out.avi"), ("two.avi",)),
    OptionTarget("unwarp", ("unwarp", "{v}", "--camera", "{s}/cam.yml.gz", "--view",
                            "panorama:64x16", "--frames", "2", "-o", "out.avi"),
                 ("video:{s}/omni.avi?rate=0", "video:{s}/omni.avi?rate=-1",
                  "video:{s}/omni.avi?rate=1e308", "video:{s}/omni.avi?loop=2",
                  "video:{s}/omni.avi?bogus=1", "images:{s}/nothing*.png", "images:",
                  "video:{s}/landmarks.csv", "{s}/landmarks.csv", "v4l2:/dev/video99",
                  "usb:zzzz:0001", "bogus:x"),
                 ("video:{s}/omni.avi?rate=1000", "video:{s}/omni.avi?loop=1")),
    # omnidev eval: task names, options, counts, reports to merge
    OptionTarget("eval", ("eval", "{v}", "--scenes", "1"),
                 ("nosuchtask", "", "../screen", "screen/x")),
    OptionTarget("eval", ("eval", "screen", "--scenes", "{v}"),
                 ("0", "-1", "abc", "nan", "99999999999999999999")),
    OptionTarget("eval", ("eval", "screen", "--scenes", "1", "--jobs", "{v}"),
                 ("-1", "abc", "nan", "99999999999999999999")),
    OptionTarget("eval", ("eval", "screen", "--scenes", "1", "--opt", "{v}"),
                 ("bogus=1", "frames_per_still=abc", "frames_per_still=-1",
                  "frames_per_still=0", "frames_per_still=99999999999999999999",
                  "frames_per_still=nan", "coded=maybe", "layout=bogus", "border=bogus", "nokey",
                  "=1")),
    OptionTarget("eval", ("eval", "laser", "--scenes", "1", "--opt", "{v}"),
                 ("frames=0", "frames=-5", "frames=9", "frames=nan", "beam_channels=2",
                  "beam_channels=7", "position=zz", "halo=-5", "colour_ratio=-0.5",
                  "busy_gain=-2", "min_cross=300", "hold_spot=3", "method=zz", "saturated=999",
                  "confirm=0", "peak_margin=-3", "cache=/proc/omnidev-none", "cache={s}/omni.png")),
    OptionTarget("eval", ("eval", "mouse", "--scenes", "1", "--opt", "{v}"),
                 ("frames=0", "frames=1", "frames=-1", "configs=zzz"), ("configs=",)),
    OptionTarget("eval", ("eval", "screen", "--scenes", "1", "--no-progress", "-o", "{v}"),
                 ("{s}", "nodir/r.json", "/dev/zero", "")),
    OptionTarget("eval", ("eval", "screen", "--scene-seed", "{v}"),
                 ("abc", "nan", "99999999999999999999999999")),
    OptionTarget("eval", ("eval", "screen", "--scene-seed", "0", "--write", "{v}"),
                 ("{s}/omni.png", "/dev/zero", "{s}")),
    OptionTarget("eval", ("eval", "screen", "--merge", "{v}"),
                 ("{s}/nothere.json", "{s}", "/dev/zero", "{s}/omni.png", "{s}/layout.json",
                  "{s}/rec.jsonl", "")),
    OptionTarget("any", ("plugins", "--max-memory", "{v}"),
                 ("abc", "-1", "nan", "inf", "1e400G"), ("0", "4G", "512M")),
)  # fmt: skip


def option_cases(seeds: Seeds) -> Iterator[Case]:
    for t in OPTION_TARGETS:
        for values, expect in ((t.refuse, "refuse"), (t.accept, "any")):
            for v in values:
                value = v.replace("{s}", str(seeds.root))
                argv = [a.replace("{s}", str(seeds.root)).replace("{v}", value) for a in t.argv]
                shown = value if len(value) < 60 else value[:20] + f"... ({len(value)} chars)"
                yield Case(t.command, f"option value {shown!r}", argv, expect=expect)  # type: ignore[arg-type]


# ------------------------------------------------------------ daemon configuration keys

_WRONG: dict[str, tuple[tuple[str, Expect], ...]] = {
    "number": (("nan", "refuse"), ("inf", "refuse"), ("-inf", "refuse"), ("-1", "refuse"),
               ('"x"', "refuse"), ("true", "refuse"), ("[]", "refuse"), ("{}", "refuse"),
               ("1e308", "refuse"), ("0", "any")),
    "int": (("nan", "refuse"), ("inf", "refuse"), ("-1", "refuse"), ("0", "refuse"),
            ("1.5", "refuse"), ('"1"', "refuse"), ("99999999999999999", "refuse")),
    "string": (("1", "refuse"), ("nan", "refuse"), ("true", "refuse"), ("[]", "refuse"),
               ('"\\u0000"', "refuse")),
    "bool": (('"yes"', "refuse"), ("1", "refuse"), ("nan", "refuse")),
}  # fmt: skip

CONFIG_KEYS: dict[str, str] = {
    "source.uri": "string",
    "tracker.name": "string",
    "tracker.options.threshold": "int",
    "tracker.options.min_area": "int",
    "filter.kind": "string",
    "filter.min_cutoff": "number",
    "filter.beta": "number",
    "filter.d_cutoff": "number",
    "sink.name": "string",
    "sink.options.path": "string",
    "buttons.dwell": "bool",
    "buttons.dwell_s": "number",
    "buttons.dwell_radius_px": "number",
    "buttons.dwell_button": "string",
    "buttons.release_when_lost": "bool",
    "screen.rect": "string",
    "screen.layout": "string",
    "daemon.socket": "string",
    "daemon.queue": "int",
    "daemon.retry_initial_s": "number",
    "daemon.retry_max_s": "number",
}
"""Every key of the fuzz seed's configuration, with its type."""


def set_key(doc: str, dotted: str, value: str) -> str:
    """The TOML text ``doc`` with ``dotted``'s value replaced by ``value`` (TOML source)."""
    *tables, key = dotted.split(".")
    header = "[" + ".".join(tables) + "]"
    lines = doc.splitlines()
    inside = False
    for i, line in enumerate(lines):
        if line.startswith("["):
            inside = line.strip() == header
            continue
        if inside and re.match(rf"{re.escape(key)}\s*=", line):
            lines[i] = f"{key} = {value}"
            return "\n".join(lines) + "\n"
    raise KeyError(dotted)


STREAM_KEYS: dict[str, str] = {
    "fps": "number",
    "queue": "int",
    "interpolation": "string",
    "max_deg_s": "number",
    "follow": "string",
    "follow_method": "string",
}
"""Keys of the streams seed (each on one line of its own), with their types."""


def set_line(doc: str, key: str, value: str) -> str:
    """The TOML text ``doc`` with the one line ``key = ...`` set to ``value``."""
    pattern = re.compile(rf"^{re.escape(key)}\s*=.*$", re.M)
    assert len(pattern.findall(doc)) == 1, key
    return pattern.sub(lambda _m: f"{key} = {value}", doc)


def config_key_cases(seeds: Seeds) -> Iterator[Case]:
    streams = seeds.text("streams.toml").decode()
    for key, kind in STREAM_KEYS.items():
        for value, expect in _WRONG[kind]:
            yield Case(
                "daemon --check",
                f"config stream {key} = {value}",
                ["daemon", "--config", "in.toml", "--check"],
                {"in.toml": set_line(streams, key, value).encode()},
                expect=expect,
            )
    doc = seeds.text("daemon.toml").decode()
    for dotted, kind in CONFIG_KEYS.items():
        for value, expect in _WRONG[kind]:
            if value == "0" and dotted in ("filter.beta", "tracker.options.threshold"):
                continue  # legal there
            text = set_key(doc, dotted, value)
            yield Case(
                "daemon --check",
                f"config {dotted} = {value}",
                ["daemon", "--config", "in.toml", "--check"],
                {"in.toml": text.encode()},
                expect=expect,
            )
    # found by the random sweep (seed 11): a positive field of view so small that tan()
    # is 0 reached the maps as a ZeroDivisionError; one too small for a finite map next
    for fov in ("5e-324", "1e-300"):
        ptz = 'view = "perspective:64x48,fov=60"'
        assert streams.count(ptz) == 1
        yield Case(
            "daemon --check",
            f"config stream view fov={fov}",
            ["daemon", "--config", "in.toml", "--check"],
            {"in.toml": streams.replace(ptz, ptz.replace("fov=60", f"fov={fov}")).encode()},
            expect="refuse",
        )
