"""Camera hardware from its sources: the paper's 1995 camera, lens and frame grabber, and a modern one.

Each ``CameraHardware`` is a frozen parameter set; every number carries its source in a
comment beside it (a datasheet, a standard or a published measurement), or says plainly that
no source was found and what stands in for it. Nothing here is fitted to the paper's accuracy
figures. ``apply_camera_hardware(cfg, hw, defects)`` puts one set into a ``SampleConfig``:
resolution and K always (the camera *is* that), and each of its defects (lens distortion,
non-square pixels, defocus at the lens's aperture, the grabber's line jitter, sensor noise)
only where ``CameraDefects`` switches it on, so that each can be studied alone. None of
them changes the ground truth: it stays the exact geometry of the camera's pixel grid.

How the 1995 focal length is worked out (the paper, V-A and V-D: a PULNiX TM-540 on a
PUMA 560, the 116.5 x 73.5 mm plate and the target block at about 40 cm; the lens is not
named). The bench's rig puts the baseline (image x) across the plate's width, so the plate's
116.5 mm length runs along the 4:3 frame's height. Filling the frame's height at 0.40 m takes
f = 0.40 m x 6.6 mm / 116.5 mm = 22.7 mm on a 2/3-inch sensor. Of the standard C-mount focal
lengths (12.5, 16, 25 mm ...), 25 mm sees 141 x 106 mm there: too small for the plate; 16 mm
sees 220 x 165 mm, which holds the plate in both views of the bench's 0.10 m baseline (they
need 73.5 + 100 = 173.5 mm across). So: a 16 mm lens. The pixel focal lengths follow from
the field of view and the 512 x 480 digitisation, not from the sensor's cell size.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace

from platebench.bench.config.sample_config import ConfigError, SampleConfig
from platebench.scenes.lens import BrownConrady
from platebench.scenes.sensor_model import SensorModel

__all__ = ["CameraHardware", "CameraDefects", "CAMERA_DEFECTS", "CAMERA_HARDWARE", "PULNIX_TM540_1995",
           "BASLER_ACA2040_55UM", "apply_camera_hardware", "camera_hardware"]

CAMERA_DEFECTS = ("distortion", "pixel_aspect", "defocus", "line_jitter", "noise")


@dataclass(frozen=True)
class CameraHardware:
    """A camera, its lens and its digitiser. Lengths in metres, pixels in pixels.

    ``fx_px``/``fy_px``: focal length over the horizontal/vertical sampling pitch; ``distortion``:
    the lens's Brown-Conrady coefficients (normalised coordinates); ``focal_length_m`` and
    ``f_number``: the thin lens (aperture radius = focal_length_m / (2 f_number)); None: no
    defocus modelled; ``sensor``: response, bit depth, noise; ``line_jitter_px``: std of the
    grabber's per-row shift."""

    name: str
    width: int
    height: int
    fx_px: float
    fy_px: float
    distortion: BrownConrady
    focal_length_m: float
    f_number: float | None
    sensor: SensorModel
    line_jitter_px: float

    @property
    def aperture_radius_m(self) -> float:
        """Entrance-pupil radius of the thin lens (m); 0 without an f-number."""
        return 0.0 if self.f_number is None else self.focal_length_m / (2.0 * self.f_number)

    @property
    def pixel_aspect(self) -> float:
        """fy / fx: the horizontal sampling pitch over the vertical one."""
        return self.fy_px / self.fx_px


# -- the paper's camera (1995) ------------------------------------------------------------------
_FORMAT_2_3_IN_M = (8.8e-3, 6.6e-3)  # 2/3-inch image area, 8.8 x 6.6 mm (4:3): Navitar, "Optical characteristics
#                                      of video lenses", image-size table. The TM-540's own datasheet was not found:
#                                      its format is an assumption (it sets only the lens's focal length in mm,
#                                      hence the aperture's size; the pixel focal lengths follow from the field).
_LENS_1995_M = 16e-3  # 16 mm C-mount lens: worked out in the module doc from the paper's geometry (V-A, V-D).

PULNIX_TM540_1995 = CameraHardware(
    name="1995",
    width=512,  # samples per line of the frame grabber: the bench's 1995 frame; no grabber datasheet found for it
    height=480,  # lines digitised from an EIA RS-170 frame (525 lines, about 480 of them active)
    fx_px=_LENS_1995_M / (_FORMAT_2_3_IN_M[0] / 512),  # 930.9 px: 16 mm over an 8.8 mm line sampled 512 times
    fy_px=_LENS_1995_M / (_FORMAT_2_3_IN_M[1] / 480),  # 1163.6 px: 16 mm over 6.6 mm and 480 lines; fy/fx = 1.25,
    #                                                    the 4:3 picture of RS-170 sampled 512 x 480 (square pixels
    #                                                    would take 640 samples a line: NDT Resource Center, frame
    #                                                    grabbers, "640 horizontally and 480 vertically")
    distortion=BrownConrady(k1=-0.228601, k2=0.190353),  # measured on "an off-the-shelf PULNiX CCD camera with
    #                                                      6 mm lens" (Zhang 1998, "A flexible new technique for
    #                                                      camera calibration", MSR-TR-98-71: k1, k2 on normalised
    #                                                      coordinates, f = 832.5 px at 640 x 480). The paper's lens
    #                                                      is not named and no measurement of a 16 mm lens of the
    #                                                      time was found: the same distortion per field angle is
    #                                                      assumed (-2.4 % at this camera's image corner).
    focal_length_m=_LENS_1995_M,
    f_number=1.4,  # widest aperture of a 16 mm f/1.4 C-mount lens (Raspberry Pi's 16 mm C-mount lens: "F1.4 to
    #                F16"). The paper's working aperture is not published: the widest is the worst case for defocus.
    sensor=SensorModel(bit_depth=8,  # 8-bit frame grabber, as the bench's 1995 camera
                       full_well_e=4000.0,  # NOT SOURCED: the TM-540's datasheet (S/N) was not found; placeholder
                       read_noise_dn=1.5,  # values stand in (full well 4000 e-, read noise 1.5 DN)
                       gamma=1.0),  # linear response (gamma switch off), as the bench's 1995 camera
    line_jitter_px=0.1,  # PLL line synchronisation of an analogue grabber: Beyer 1992 ("Advances in characterisation
    #                      and calibration of digital imaging systems", IAPRS XXIX-B5, p. 545ff) measured pixel-
    #                      synchronous sampling to below 0.005 px and "a factor of 20 better" than PLL line-
    #                      synchronisation via CSYNC: 20 x 0.005 = 0.1 px, read as the std of the per-line shift.
)

# -- a modern machine-vision camera ----------------------------------------------------------------
_PIXEL_MODERN_M = 3.45e-6  # Basler acA2040-55um: Sony IMX265, 3.45 x 3.45 um pixels (Basler docs, specifications)
_LENS_MODERN_M = 12e-3  # 12 mm C-mount lens: the longest standard focal length whose field at 0.40 m (236 x 177 mm
#                         on the 7.07 mm wide sensor) holds the plate in both views of the 0.10 m baseline (173.5 mm;
#                         16 mm sees 177 mm: too tight)

BASLER_ACA2040_55UM = CameraHardware(
    name="modern",
    width=2048,  # Basler acA2040-55um default resolution 2048 x 1536 (Basler docs, specifications)
    height=1536,  # idem
    fx_px=_LENS_MODERN_M / _PIXEL_MODERN_M,  # 3478 px: 12 mm over 3.45 um
    fy_px=_LENS_MODERN_M / _PIXEL_MODERN_M,  # square pixels (3.45 x 3.45 um, Basler docs)
    distortion=BrownConrady(),  # NOT SOURCED: no published measurement of a modern 12 mm machine-vision lens was
    #                             found; none is modelled
    focal_length_m=_LENS_MODERN_M,
    f_number=None,  # NOT SOURCED: the working aperture depends on the set-up; no defocus is modelled
    sensor=SensorModel(bit_depth=16,  # digital output, stored in 16 bits as the bench's modern camera
                       full_well_e=20000.0,  # NOT SOURCED: the IMX265's EMVA 1288 data were not found; placeholder
                       read_noise_dn=3.0,  # values stand in (full well 20000 e-, read noise 3 DN)
                       gamma=1.0),
    line_jitter_px=0.0,  # a digital (USB3 Vision) camera sends its pixels: no analogue line to re-sample (Beyer 1992:
    #                      pixel-synchronous sampling is below 0.005 px already)
)

CAMERA_HARDWARE = {"1995": PULNIX_TM540_1995, "modern": BASLER_ACA2040_55UM}


def camera_hardware(name: str) -> CameraHardware:
    """The parameter set called ``name`` (``CAMERA_HARDWARE``); a one-line error otherwise."""
    if name not in CAMERA_HARDWARE:
        raise ConfigError(f"camera hardware {name!r} is not known: choose one of {', '.join(CAMERA_HARDWARE)}")
    return CAMERA_HARDWARE[name]


@dataclass(frozen=True)
class CameraDefects:
    """Which of a camera's defects are modelled (all by default: the camera as it is).

    ``distortion``: its lens's distortion; ``pixel_aspect``: its non-square pixels (off: fy = fx,
    the horizontal pitch both ways); ``defocus``: the thin lens at its f-number, focused on the
    plate centre (off: a pinhole); ``line_jitter``: the grabber's per-row shift; ``noise``: shot
    and read noise (off: noise-free; the bit depth stays the camera's)."""

    distortion: bool = True
    pixel_aspect: bool = True
    defocus: bool = True
    line_jitter: bool = True
    noise: bool = True

    @classmethod
    def none(cls) -> "CameraDefects":
        return cls(**dict.fromkeys(CAMERA_DEFECTS, False))

    @classmethod
    def only(cls, *names: str) -> "CameraDefects":
        """Just the defects ``names`` (each one of ``CAMERA_DEFECTS``)."""
        _check_names(names)
        return cls(**{n: n in names for n in CAMERA_DEFECTS})

    def without(self, *names: str) -> "CameraDefects":
        """These defects less ``names``."""
        _check_names(names)
        return replace(self, **dict.fromkeys(names, False))

    def on(self) -> tuple[str, ...]:
        return tuple(f.name for f in fields(self) if getattr(self, f.name))


def _check_names(names) -> None:
    bad = [n for n in names if n not in CAMERA_DEFECTS]
    if bad:
        raise ConfigError(f"camera defect {bad[0]!r} is not known: choose from {', '.join(CAMERA_DEFECTS)}")


def apply_camera_hardware(cfg: SampleConfig, hw: CameraHardware,
                          defects: CameraDefects = CameraDefects()) -> SampleConfig:
    """``cfg`` seen through ``hw``: its resolution and focal lengths, and the defects switched on.

    The plate, distance, baseline, projector, material and render settings of ``cfg`` are kept;
    its camera (size, f, fy, distortion, aperture and focus, sensor model) is replaced."""
    fy = hw.fy_px if defects.pixel_aspect and abs(hw.fy_px - hw.fx_px) > 0 else None
    scene = replace(cfg.scene, width=hw.width, height=hw.height, f_px=hw.fx_px, fy_px=fy,
                    distortion=asdict(hw.distortion) if defects.distortion and not hw.distortion.is_identity else {},
                    aperture_radius_m=hw.aperture_radius_m if defects.defocus else 0.0,
                    focus_distance_m=None)
    s = hw.sensor
    sensor = replace(s, full_well_e=s.full_well_e if defects.noise else 0.0,
                     read_noise_dn=s.read_noise_dn if defects.noise else 0.0,
                     line_jitter_px=hw.line_jitter_px if defects.line_jitter else 0.0)
    return replace(cfg, scene=scene, sensor=sensor)
