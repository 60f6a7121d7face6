# Type hints of the morphray Python package (the implementation is morphray/__init__.py and the
# native module). Scene options are keyword arguments by the command line's names
# (`morphray.scene_options()` lists them; `morphray render --help` explains each).
from os import PathLike
from typing import Any, Literal, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

class Error(Exception): ...
class InputError(Error): ...
class DeviceError(Error): ...
class MemoryBudgetError(Error): ...

Colour = Union[str, Tuple[int, int, int]]
SceneOption = Any  # str | float | bool | tuple | list | dict, as scene_options() describes

def configure(
    device: Optional[Union[int, str]] = ...,
    memory_budget: Optional[int] = ...,
    validation: bool = ...,
) -> None: ...
def device_name() -> str: ...
def scene_options() -> list[Tuple[str, str, list[str], str, str]]: ...
def open(
    source: Union[str, PathLike[str], Any, Tuple[npt.ArrayLike, npt.ArrayLike]],
    frame: int = ...,
    series: Optional[Union[int, str]] = ...,
    normalize: Literal["robust", "minmax"] = ...,
    contrast: Literal["auto", "t1", "t2", "pd", "flair"] = ...,
    modality: Literal["auto", "mr", "ct", "pt", "other"] = ...,
    **scene: SceneOption,
) -> Volume: ...
def phantom(
    shape: Tuple[int, int, int] = ...,
    seed: Optional[int] = ...,
    noise: bool = ...,
    head: bool = ...,
    spacing: float = ...,
    normalize: Literal["robust", "minmax"] = ...,
    **scene: SceneOption,
) -> Volume: ...

class Volume:
    @property
    def label(self) -> str: ...
    @property
    def shape(self) -> Tuple[int, int, int]: ...
    @property
    def warnings(self) -> list[str]: ...
    @property
    def layout(self) -> Literal["whole", "bricked"]: ...
    @property
    def affine(self) -> npt.NDArray[np.float64]: ...
    @property
    def spacing(self) -> Tuple[float, float, float]: ...
    @property
    def header(self) -> dict[str, Any]: ...
    def __array__(self, dtype: Any = ..., copy: Optional[bool] = ...) -> np.ndarray: ...
    def peaks(self) -> dict[str, Any]: ...
    def render(
        self,
        scene: Optional[Union[str, PathLike[str]]] = ...,
        layers: Optional[Union[str, PathLike[str], Sequence[Union[str, PathLike[str]]]]] = ...,
        *,
        size: Union[int, Tuple[int, int], str] = ...,
        mode: Literal["dvr", "mip", "minip"] = ...,
        tissues: Union[str, Sequence[str]] = ...,
        preset: str = ...,
        brain: Literal["auto", "on", "off"] = ...,
        windows: Literal["adaptive", "paper"] = ...,
        view: Literal["anterior", "posterior", "left", "right", "superior", "inferior"] = ...,
        azimuth: float = ...,
        elevation: float = ...,
        zoom: float = ...,
        pan: Tuple[float, float] = ...,
        projection: Literal["perspective", "orthographic"] = ...,
        step: float = ...,
        curvature: Union[bool, Literal["on", "off"]] = ...,
        shading: Union[bool, Literal["on", "off"]] = ...,
        lighting: Literal["headlight", "studio", "matcap"] = ...,
        matcap: Union[Literal["clay", "shiny"], str, PathLike[str]] = ...,
        depth_cues: Union[bool, Literal["on", "off"]] = ...,
        cue_strength: str = ...,
        cutaway: Union[Literal["centre"], Tuple[float, float, float], str] = ...,
        gradient: Literal["precomputed", "on-the-fly"] = ...,
        derived_precision: Literal["8bit", "f16", "f32"] = ...,
        classification: Literal["table", "exact", "volume"] = ...,
        background: Colour = ...,
        no_jitter: bool = ...,
        jitter: bool = ...,
        window: Union[Mapping[str, Tuple[float, float]], str, Sequence[str]] = ...,
        opacity: Union[Mapping[str, float], str, Sequence[str]] = ...,
        color: Union[Mapping[str, Colour], str, Sequence[str]] = ...,
        crop: Union[Tuple[Tuple[float, float], Tuple[float, float], Tuple[float, float]], str] = ...,
        clip_plane: Union[Tuple[float, float, float, float], Sequence[Tuple[float, float, float, float]], str] = ...,
        colormap: Literal["gray", "hot", "viridis", "inferno", "bone"] = ...,
        denoise: str = ...,
        **more: SceneOption,
    ) -> npt.NDArray[np.uint8]: ...
    def derive(
        self,
        maps: Union[str, Sequence[str]] = ...,
        denoise: str = ...,
        vessel_scales: Optional[Sequence[float]] = ...,
    ) -> dict[str, np.ndarray]: ...
    def to_nifti(
        self, path: Union[str, PathLike[str]], data: Optional[npt.ArrayLike] = ..., force: bool = ...
    ) -> None: ...
    def to_nibabel(self, data: Optional[npt.ArrayLike] = ...) -> Any: ...
    def brain_report(self) -> dict[str, Any]: ...
    def save_scene(
        self,
        path: Union[str, PathLike[str]],
        layers: Optional[Union[str, PathLike[str], Sequence[Union[str, PathLike[str]]]]] = ...,
        **options: SceneOption,
    ) -> None: ...
