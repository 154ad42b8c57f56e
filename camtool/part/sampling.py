"""Numbers the part stage's readers and segmentation share: how small a coordinate is no length, and how
densely sampled points make a connected piece and a face."""

TINY_COORDINATE = 1e-30   # mm: a non-zero coordinate below this is no length a workpiece file holds
CONNECT_SPACINGS = 6.0    # points closer than this many median nearest-neighbour spacings are connected
MIN_FACE_SAMPLES = 30     # a round whose best face holds fewer sample points ends the search
