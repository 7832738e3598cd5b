"""Reading one image file a user names, without trusting it.

The file must be a regular file of at most ``MAX_IMAGE_BYTES``; its header is read first
(Pillow reads only the header) and an image larger than ``MAX_IMAGE_SIDE_PX`` on a side or
``MAX_IMAGE_PIXELS`` in all is refused before it is decoded, so a small "decompression bomb" file
cannot exhaust memory. A PNG or JPEG is also sized as its decoder (libpng, libjpeg) will read it
(:mod:`umbra.connectors.image_header`): a frame header hidden behind JPEG fill bytes cannot pass as
a small image. Grayscale and palette images come back as 3-channel BGR like colour ones.
"""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np

from umbra.connectors.errors import UserError
from umbra.connectors.image_header import image_size
from umbra.connectors.limits import MAX_IMAGE_FILE_BYTES as MAX_IMAGE_BYTES
from umbra.connectors.limits import MAX_IMAGE_SIDE_PX
from umbra.connectors.limits import MAX_PHOTO_PIXELS as MAX_IMAGE_PIXELS
from umbra.connectors.user_files import read_bytes


def read_image(path: str | Path) -> np.ndarray:
    """The image at ``path`` as ``(height, width, 3)`` uint8 BGR; UserError saying why not."""
    import cv2
    from PIL import Image, UnidentifiedImageError

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
    if data[:8] == b"\x89PNG\r\n\x1a\n" or data[:2] == b"\xff\xd8":
        try:
            decoded_size = image_size(data)
        except ValueError as exc:
            raise UserError(f"{path}: error: cannot read it as an image: {exc}") from None
        if decoded_size != (width, height):
            width, height = max(width, decoded_size[0]), max(height, decoded_size[1])
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
