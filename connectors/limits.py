"""Physical and scheduling envelopes that safety-relevant parameters are bounded by.

The numbers are what an arm of the Puma 560 class can do (a 0.86 m reach at the shoulder's
1.3 rad/s gives about 1.1 m/s at the tool) and what the scheduler can run; a parameter beyond them
cannot be a real setting, only a mistake that disarms a guard (``timeout: .inf``,
``max_linear: 1e9``, ``rate: 1e-300``).
"""

from __future__ import annotations

import math

#: Fastest tool translation a command may ask for [m/s].
MAX_TOOL_SPEED_M_S = 1.0
#: Fastest tool rotation a command may ask for [rad/s] (half a turn per second).
MAX_TOOL_ANGULAR_RAD_S = math.pi
#: Longest time a watchdog may trust a command or a joint state [s].
MAX_COMMAND_AGE_S = 1.0
#: Oldest sensor data a guard may let a command be made from [s] (``max_origin_age``).
MAX_ORIGIN_AGE_S = 2.0
#: Oldest snapshot a planned path may be played from [s] (``max_path_age``): an hour.
MAX_PATH_AGE_S = 3600.0
#: Highest module rate the scheduler runs [Hz].
MAX_RATE_HZ = 10_000.0
#: Lowest module rate [Hz]: one tick every 1000 s; a graph that ticks less is a mistake.
MIN_RATE_HZ = 1e-3
#: Largest joint acceleration a simulated or real drive is asked for [rad/s^2].
MAX_JOINT_ACCEL_RAD_S2 = 1000.0
#: Largest image side a module allocates [px].
MAX_IMAGE_SIDE_PX = 8192
#: Most pixels of an image a reader decodes (a header declaring more is refused undecoded).
MAX_IMAGE_PIXELS = MAX_IMAGE_SIDE_PX * MAX_IMAGE_SIDE_PX
#: Largest record of a recording, and largest chunk once inflated [bytes]: one raw image of the
#: largest side at 4 bytes a pixel, with room for its envelope. A longer record or a chunk that
#: declares (or inflates to) more is refused before it is read or inflated.
MAX_RECORDING_RECORD_BYTES = 4 * MAX_IMAGE_PIXELS + (1 << 20)
#: Largest text file a module reads (DH tables, calibration files, CSV) [bytes].
MAX_TEXT_FILE_BYTES = 4_000_000
#: Largest sketch session file (``session.json``) read [bytes].
MAX_SKETCH_SESSION_BYTES = 1_000_000
#: Most commands a sketch session replays (every call replays them all).
MAX_SKETCH_SESSION_EVENTS = 1000
#: Largest image file a module reads (a photo background, a test image) [bytes].
MAX_IMAGE_FILE_BYTES = 64_000_000
#: Most pixels of an image file decoded (a 6000 x 4000 photo has 24 million).
MAX_PHOTO_PIXELS = 40_000_000

# -- the door of every web server of a run (connectors/access/door.py: the operator's pages in
# modules/webdoor, the live server in runtime/live): what one client may make a server hold --
#: Largest request head (request line and headers) a server reads (a page, an upgrade) [bytes].
MAX_PAGE_HEAD_BYTES = 16 * 1024
#: Largest request body a page server reads (a sketch command is at most 2000 characters) [bytes].
MAX_PAGE_BODY_BYTES = 16 * 1024
#: Largest websocket message a page may send (its commands are small JSON objects) [bytes].
MAX_PAGE_MESSAGE_BYTES = 4096
#: Open connections to one server (a page server, the live server), every client together.
MAX_PAGE_CONNECTIONS = 64
#: Open connections to one server from one client address (loopback: every local client).
MAX_PAGE_CONNECTIONS_PER_CLIENT = 32
#: Connections the kernel queues for a server until it accepts them, and that it accepts at once.
MAX_PAGE_ACCEPT_BACKLOG = 128
#: Longest a request may take to arrive whole, head then body [s] (a websocket upgrade: its head).
MAX_PAGE_REQUEST_S = 5.0
#: Messages a page may send on its socket per second, sustained (a held jog, the painted reports
#: of 30 fps video and the seen reports of the console's states are about 65, 115 at the console's
#: highest state rate) and in a burst; beyond either its socket is closed.
MAX_PAGE_MESSAGES_PER_S = 120.0
MAX_PAGE_MESSAGE_BURST = 240
#: Malformed or refused-as-replayed messages after which a page's socket is closed.
MAX_PAGE_BAD_MESSAGES = 20
#: Updates of one kind (video frames, states, the 3-D view's scene) a page server sends a page
#: and the page has not yet said it applied: hides the round trip, never a queue.
MAX_PAGE_IN_FLIGHT = 2
#: Longest a page server waits for a page to say it applied an update before it sends another
#: all the same [s]: a page that does not say (a script, a stuck tab) is paced, never stopped.
PAGE_ACK_TIMEOUT_S = 1.0

# -- the live Foxglove server (runtime/live): what one viewer may make it hold --
#: Largest message a viewer may send (a subscription to every channel of a big graph is ~4 KiB).
MAX_VIEWER_MESSAGE_BYTES = 64 * 1024
#: Viewers connected at once.
MAX_VIEWERS = 16
#: Messages held for a viewer that does not keep up, per viewer; then its oldest data is dropped
#: (about half a second of a pick-up's image and joint streams).
MAX_VIEWER_BACKLOG = 64
#: ... and bytes held for it (about ten 640 x 480 JPEG frames: a viewer that falls behind sees
#: fresh video again within a third of a second, not a backlog of old frames).
MAX_VIEWER_BACKLOG_BYTES = 512 * 1024
