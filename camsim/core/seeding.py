"""Every seed camsim derives, in one place: one documented namespace per consumer.

All randomness comes from numpy ``SeedSequence`` objects built here from a user's seed; no global generator is
used anywhere. The namespaces (``spawn_key`` prefixes) keep consumers apart, so that no two ever draw the same
stream:

==========================  =======================================================  ==================
consumer                    seed sequence                                            function
==========================  =======================================================  ==================
a scene frame               ``SeedSequence(seed, spawn_key=(crc32(label), c))``      :func:`frame_seed_sequence`
  (``render``, ``dataset``, with c = ``crc32(repr(F))``; ``label`` is the
  experiments)              illuminant (render, dataset) or the experiment's
                            series name
a row block of a frame      child *b* of the frame's sequence (``spawn``)            :func:`block_generators`
a sensor's fixed pattern    ``SeedSequence(sensor_seed, spawn_key=(0x46504E,))``,    :func:`fixed_pattern_generators`
                            children 0 (DSNU offset), 1 (PRNU) and 2 (dark-current
                            DSNU)
  (issue 28's maps)         children 3 (defect population), 4 (hot pixels' dark      :func:`fixed_pattern_generator`
                            current), 5 (stuck levels), 6 (dark shading), 7 (column
                            FPN)
a frame's black-level       the frame's sequence extended by the word ``0xB1AC0``    :func:`frame_effect_generator`
  error                     and the number of children it has spawned (its blocks
                            are children 0, 1, … of the frame's sequence)
a dataset frame's seed      ``SeedSequence(spec seed, spawn_key=sha256(id)[:16] as   :func:`dataset_frame_seed`
                            4 words)``, its first 64-bit word >> 11 (< 2^53)
a dataset random parameter  ``SeedSequence(spec seed, spawn_key=(0xDA7A5E7,          :func:`dataset_parameter_generator`
                            crc32(name)))``
an EMVA 1288 frame          ``SeedSequence(seed, spawn_key=(kind, step, frame))``    :func:`emva_frame_seed_sequence`
a synthetic target's        ``SeedSequence(target seed, spawn_key=(0x7A263E7,))``    :func:`target_generator`
  pattern (dead leaves)
a batch of training pairs   ``SeedSequence(seed, spawn_key=(0x9A125, hi, lo))`` for  :func:`pair_batch_seed_sequence`
  (:mod:`camsim.pairs`)     batch b, hi = ``b >> 32``, lo = ``b & 0xFFFFFFFF``;
                            children 0 (noise), 1 (images and crops), 2 (light),
                            3–8 (cameras)
==========================  =======================================================  ==================

Frame keys have two words, dataset frame-seed keys four, parameter keys start with ``0xDA7A5E7`` and the fixed
pattern's with ``0x46504E`` (neither a CRC-32 collision with a frame key in practice nor a small EMVA kind), so
the namespaces are disjoint by the length or the first word of their keys. A target's pattern has a one-word key
(``0x7A263E7``, "TARGET"), like the fixed pattern's but a different word: a scene's target seed and its frames' noise
seed may be the same number and still never share a stream. A batch of training pairs has a three-word key, like an
EMVA frame's, whose first word ``0x9A125`` ("PAIRS") is no small EMVA kind.
"""

from __future__ import annotations

import hashlib
import zlib

import numpy as np

#: First spawn-key word of the fixed-pattern maps ("FPN").
FIXED_PATTERN_KEY = 0x46504E
#: First spawn-key word of a dataset's random parameter streams.
DATASET_PARAMETER_KEY = 0xDA7A5E7
#: Spawn-key word of a synthetic target's pattern (a dead-leaves chart).
TARGET_KEY = 0x7A263E7
#: First spawn-key word of a batch of training pairs ("PAIRS").
PAIRS_KEY = 0x9A125


def frame_seed_sequence(seed: int, label: str, intensity_factor: float) -> np.random.SeedSequence:
    """The seed sequence of one frame: a function of the run seed, the label (the illuminant) and F only.

    So a frame is the same whether it is rendered alone or as part of a longer run.
    """
    key = (zlib.crc32(label.encode("utf-8")), zlib.crc32(repr(float(intensity_factor)).encode("ascii")))
    return np.random.SeedSequence(entropy=seed, spawn_key=key)


def block_generators(rng, count: int) -> list[np.random.Generator]:
    """One generator per row block of a frame: child *b* of ``rng`` for block *b*.

    ``rng`` is a ``Generator`` (spawned), a ``SeedSequence`` or an int seed (spawned into PCG64 generators), so
    that a frame's output does not depend on how many threads draw its blocks.
    """
    if isinstance(rng, np.random.Generator):
        return rng.spawn(count)
    seed_seq = rng if isinstance(rng, np.random.SeedSequence) else np.random.SeedSequence(rng)
    return [np.random.Generator(np.random.PCG64(child)) for child in seed_seq.spawn(count)]


def fixed_pattern_generators(sensor_seed: int) -> tuple[np.random.Generator, ...]:
    """The generators of a sensor's unit maps — DSNU offset, PRNU, dark-current DSNU — a function of ``sensor_seed``
    alone.

    Child *i* of a ``SeedSequence`` depends on *i* only, not on how many are spawned, so the dark-current map
    (child 2, added later) left the offset and gain maps (children 0 and 1) as they were.
    """
    children = np.random.SeedSequence(sensor_seed, spawn_key=(FIXED_PATTERN_KEY,)).spawn(3)
    return tuple(np.random.Generator(np.random.PCG64(child)) for child in children)


def fixed_pattern_generator(sensor_seed: int, index: int) -> np.random.Generator:
    """Child ``index`` of a sensor's fixed-pattern sequence (:func:`fixed_pattern_generators` holds 0 to 2): 3 the
    defect population, 4 the hot pixels' dark current, 5 the stuck pixels' levels, 6 the dark shading, 7 the column
    FPN. Child *i* depends on *i* alone, so each map leaves the others as they were."""
    child = np.random.SeedSequence(sensor_seed, spawn_key=(FIXED_PATTERN_KEY,)).spawn(index + 1)[index]
    return np.random.Generator(np.random.PCG64(child))


#: Spawn-key word of a frame's per-frame effects (the black-level error), after the frame's own key.
FRAME_EFFECT_KEY = 0xB1AC0


def frame_effect_generator(rng) -> np.random.Generator:
    """A generator of a frame's per-frame effects (the black-level error), derived from the frame's seed ``rng``
    (a ``SeedSequence``, an int, or a numpy ``Generator`` seeded from one) without drawing from it or spawning
    it: the frame's other draws (its row blocks, children 0, 1, … of its sequence) stay as they were. Its key is
    the frame's key extended by :data:`FRAME_EFFECT_KEY`, far above any block index, and by the number of children
    the sequence has spawned so far: frames drawn one after another from one generator or sequence (each frame
    spawns its blocks from it) get effects of their own, as they get blocks of their own.

    Raises
    ------
    ValueError
        ``rng`` is None or a generator without a seed sequence (a CuPy generator): no seed to derive from.
    """
    if isinstance(rng, np.random.Generator):
        rng = getattr(rng.bit_generator, "seed_seq", None)
    elif isinstance(rng, (int, np.integer)) and not isinstance(rng, bool):
        rng = np.random.SeedSequence(int(rng))
    if not isinstance(rng, np.random.SeedSequence):
        raise ValueError("a per-frame effect needs the frame's seed (a SeedSequence, an int or a numpy Generator)")
    sequence = np.random.SeedSequence(rng.entropy, pool_size=rng.pool_size,
                                      spawn_key=tuple(rng.spawn_key) + (FRAME_EFFECT_KEY, rng.n_children_spawned))
    return np.random.Generator(np.random.PCG64(sequence))


def dataset_frame_seed(spec_seed: int, frame_id: str) -> int:
    """A dataset frame's seed: a function of the spec seed and the frame id only, below 2**53 (exact in JSON)."""
    digest = hashlib.sha256(frame_id.encode("utf-8")).digest()
    key = tuple(int.from_bytes(digest[i: i + 4], "little") for i in range(0, 16, 4))
    state = np.random.SeedSequence(entropy=spec_seed, spawn_key=key).generate_state(1, np.uint64)[0]
    return int(state) >> 11


# NumPy's SeedSequence constants (numpy/random/bit_generator.pyx, after M. E. O'Neill's seed_seq), for
# dataset_frame_seeds, which repeats its mixing on arrays
_INIT_A, _MULT_A, _INIT_B, _MULT_B = 0x43B0D7E5, 0x931E8875, 0x8B51F9DD, 0x58F38DED
_MIX_MULT_L, _MIX_MULT_R, _MASK32 = 0xCA01F9DD, 0x4973F715, 0xFFFFFFFF
_POOL_SIZE = 4


def dataset_frame_seeds(spec_seed: int, frame_ids) -> list[int]:
    """:func:`dataset_frame_seed` of many frames at once: the same numbers, some 30 times faster per frame.

    NumPy's ``SeedSequence(entropy=spec_seed, spawn_key=...).generate_state(1, np.uint64)``, its entropy mixing
    done once for all the frames on arrays of 32-bit words (a test checks it against SeedSequence itself).

    Parameters
    ----------
    spec_seed : int
        The spec's seed (≥ 0).
    frame_ids : sequence of str

    Returns
    -------
    list of int
        One seed per frame id, each < 2**53.
    """
    if not frame_ids:
        return []
    digests = b"".join(hashlib.sha256(frame_id.encode("utf-8")).digest()[:16] for frame_id in frame_ids)
    spawn = np.frombuffer(digests, dtype="<u4").reshape(len(frame_ids), 4).astype(np.uint32)
    run = _uint32_words(spec_seed)
    run += [0] * (_POOL_SIZE - len(run))  # as SeedSequence pads the entropy of a spawned sequence
    columns = [np.full(len(frame_ids), word, dtype=np.uint32) for word in run] + list(spawn.T)
    pool = _mix_entropy(columns)
    state = [_output_word(pool[i], i) for i in range(2)]  # generate_state(1, uint64): two words, little-endian
    return ((state[0].astype(np.uint64) | (state[1].astype(np.uint64) << np.uint64(32))) >> np.uint64(11)).tolist()


def _uint32_words(value: int) -> list[int]:
    """A non-negative integer as SeedSequence takes it: 32-bit words, least significant first ([0] for 0)."""
    words = [value & _MASK32]
    value >>= 32
    while value:
        words.append(value & _MASK32)
        value >>= 32
    return words


class _HashConstant:
    """The running hash constant of SeedSequence's mixing (a 32-bit word, the same for every frame)."""

    def __init__(self, value: int):
        self.value = value

    def hashmix(self, words: np.ndarray) -> np.ndarray:
        words = words ^ np.uint32(self.value)
        self.value = (self.value * _MULT_A) & _MASK32
        words = words * np.uint32(self.value)
        return words ^ (words >> np.uint32(16))


def _mix(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    result = np.uint32(_MIX_MULT_L) * x - np.uint32(_MIX_MULT_R) * y
    return result ^ (result >> np.uint32(16))


def _mix_entropy(entropy: list) -> list:
    """SeedSequence.mix_entropy on columns of 32-bit words (one array per entropy word, one element per frame)."""
    const = _HashConstant(_INIT_A)
    mixer = [const.hashmix(entropy[i]) for i in range(_POOL_SIZE)]
    for i_src in range(_POOL_SIZE):
        for i_dst in range(_POOL_SIZE):
            if i_src != i_dst:
                mixer[i_dst] = _mix(mixer[i_dst], const.hashmix(mixer[i_src]))
    for i_src in range(_POOL_SIZE, len(entropy)):
        for i_dst in range(_POOL_SIZE):
            mixer[i_dst] = _mix(mixer[i_dst], const.hashmix(entropy[i_src]))
    return mixer


def _output_word(pool_word: np.ndarray, i: int) -> np.ndarray:
    """Word ``i`` of SeedSequence.generate_state (i < the pool size)."""
    const = _INIT_B
    for _ in range(i):
        const = (const * _MULT_B) & _MASK32
    words = pool_word ^ np.uint32(const)
    words = words * np.uint32((const * _MULT_B) & _MASK32)
    return words ^ (words >> np.uint32(16))


def dataset_parameter_generator(spec_seed: int, name: str) -> np.random.Generator:
    """The stream of a dataset's random parameter ``name``: its draws do not move when others are added."""
    stream = np.random.SeedSequence(entropy=spec_seed, spawn_key=(DATASET_PARAMETER_KEY,
                                                                  zlib.crc32(name.encode("utf-8"))))
    return np.random.default_rng(stream)


def emva_frame_seed_sequence(seed: int, kind: int, step: int, frame: int) -> np.random.SeedSequence:
    """The seed sequence of one EMVA 1288 frame: measurement ``kind``, irradiation ``step``, ``frame`` of it."""
    return np.random.SeedSequence(seed, spawn_key=(kind, step, frame))


def target_generator(seed: int) -> np.random.Generator:
    """The stream of a synthetic target's pattern (:mod:`camsim.scene.sources.target`): a function of its ``seed``
    alone."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(TARGET_KEY,)))


def pair_batch_seed_sequence(seed: int, index: int) -> np.random.SeedSequence:
    """The seed sequence of batch ``index`` of training pairs (:mod:`camsim.pairs`): a function of the seed and the
    batch index only, so that a batch is the same whichever worker draws it and whatever was drawn before."""
    index = int(index)
    return np.random.SeedSequence(entropy=seed, spawn_key=(PAIRS_KEY, index >> 32, index & 0xFFFFFFFF))
