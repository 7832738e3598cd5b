"""Reading one image file a user names, without trusting it.

The file must be a regular file of at most ``MAX_IMAGE_BYTES``; its header is read first
(Pillow reads only the header) and an image larger than ``MAX_IMAGE_SIDE_PX`` on a side or
``MAX_IMAGE_PIXELS`` in all is refused before it is decoded, so a small "decompression bomb" file
cannot exhaust memory. Grayscale and palette images come back as 3-channel BGR like colour ones.
"""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import cv2
import numpy as np
from PIL import Image, UnidentifiedImageError

from connectors.errors import UserError
from connectors.limits import MAX_IMAGE_SIDE_PX
from connectors.user_files import read_bytes

#: Largest image file read [bytes].
MAX_IMAGE_BYTES = 64_000_000
#: Most pixels of an image decoded (a 6000 x 4000 photo has 24 million).
MAX_IMAGE_PIXELS = 40_000_000


def read_image(path: str | Path) -> np.ndarray:
    """The image at ``path`` as ``(height, width, 3)`` uint8 BGR; UserError saying why not."""
    data = read_bytes(path, "image file", MAX_IMAGE_BYTES)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # Pillow's own bomb warning: we check the size below
            with Image.open(io.BytesIO(data)) as header:
                width, height = header.size
    except Image.DecompressionBombError as exc:  # far beyond our bound too
        raise UserError(f"{path}: error: image is too large to decode: {exc}") from None
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError):
        raise UserError(
            f"{path}: error: cannot read it as an image (expected PNG, JPEG, BMP, TIFF...)"
        ) from None
    if width > MAX_IMAGE_SIDE_PX or height > MAX_IMAGE_SIDE_PX or width * height > MAX_IMAGE_PIXELS:
        raise UserError(
            f"{path}: error: image is {width}x{height} px; at most {MAX_IMAGE_SIDE_PX} px a side "
            f"and {MAX_IMAGE_PIXELS} pixels"
        )
    image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
    if image is None or image.size == 0:
        raise UserError(
            f"{path}: error: cannot decode it as an image (expected PNG, JPEG, BMP, TIFF...)"
        )
    return image
