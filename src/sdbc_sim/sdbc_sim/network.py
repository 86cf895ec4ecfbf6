"""The controller: a feed-forward network with one hidden layer.

docs/reference-setup.md, "Neural controller".

Inputs are linear; the hidden and output units are sigmoids with a bias:

    h_j = sigma(b_j + sum_i W1[j, i] x_i),     o_k = sigma(c_k + sum_j W2[k, j] h_j),
    sigma(a) = 1 / (1 + exp(-a)).

Genome layout (direct encoding, ``genome_length = (I + 1) H + (H + 1) O``): first the
hidden layer, one row per hidden unit j holding its I input weights then its bias
b_j; then the output layer, one row per output unit k holding its H weights then its
bias c_k. Teams are homogeneous: every robot of a trial runs its trial's genome.

The sums run in a fixed order (i = 0..I-1, then j = 0..H-1) as element-wise array
operations rather than through BLAS, whose summation order may depend on the matrix
sizes: a robot's outputs are then the same to the bit whatever else shares the batch.
A process that steps the physics has numba loaded (:mod:`sdbc_sim.compiled`) and
adds them in a compiled loop, in the same order, so to the same bits; a controller
node, which never loads numba, adds them with numpy.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sdbc_sim import compiled


@dataclass(frozen=True)
class NetworkShape:
    """Layer sizes of the controller network.

    Attributes:
        n_inputs: I, the number of sensor inputs.
        n_hidden: H, the number of hidden sigmoid units.
        n_outputs: O, the number of output sigmoid units.
    """

    n_inputs: int
    n_hidden: int
    n_outputs: int

    def __post_init__(self) -> None:
        for name in ("n_inputs", "n_hidden", "n_outputs"):
            if getattr(self, name) < 1:
                raise ValueError(
                    f"network: {name} must be >= 1, got {getattr(self, name)}"
                )

    @property
    def genome_length(self) -> int:
        """(I + 1) H + (H + 1) O weights, biases included."""
        return (self.n_inputs + 1) * self.n_hidden + (
            self.n_hidden + 1
        ) * self.n_outputs


def check_genomes(genomes: np.ndarray, shape: NetworkShape) -> np.ndarray:
    """Returns ``genomes`` as a float64 (G, W) array, or raises ValueError.

    Raises:
        ValueError: If the array is not 2-D, a genome does not have
            ``shape.genome_length`` weights, or a weight is NaN or infinite.
    """
    g = np.asarray(genomes, dtype=np.float64)
    if g.ndim != 2:
        raise ValueError(f"genomes: expected a (G, W) array, got shape {g.shape}")
    if g.shape[1] != shape.genome_length:
        raise ValueError(
            f"genomes: length {g.shape[1]} does not match the network "
            f"{shape.n_inputs}-{shape.n_hidden}-{shape.n_outputs}, which needs "
            f"{shape.genome_length} weights"
        )
    bad = ~np.isfinite(g)
    if bad.any():
        rows = np.unique(np.nonzero(bad)[0])
        raise ValueError(
            f"genomes: NaN or infinite weights in genome(s) {rows[:10].tolist()}"
        )
    return g


def sigmoid(a: np.ndarray) -> np.ndarray:
    """The logistic function 1 / (1 + exp(-a)), in place on ``a``."""
    np.negative(a, out=a)
    np.exp(a, out=a)
    a += 1.0
    np.reciprocal(a, out=a)
    return a


class TeamNetworks:
    """The networks of a batch of teams: every robot of trial b runs genome b.

    Weights are stored once per trial, source-unit-major with the trials
    innermost, (inputs, units, B); the robots' values are (units, N, B). A layer
    is then a short fixed sequence of multiply-adds over long contiguous rows,
    each weight row read once for the N robots of its trials.

    Args:
        shape: The layer sizes.
        genomes: (B, W) float64, the genome of each trial; already checked.
    """

    def __init__(self, shape: NetworkShape, genomes: np.ndarray) -> None:
        self.shape = shape
        n_in, n_hid, n_out = shape.n_inputs, shape.n_hidden, shape.n_outputs
        b = genomes.shape[0]
        split = (n_in + 1) * n_hid
        hidden = genomes[:, :split].reshape(b, n_hid, n_in + 1)
        output = genomes[:, split:].reshape(b, n_out, n_hid + 1)
        self.w_hidden = np.ascontiguousarray(hidden[:, :, :n_in].transpose(2, 1, 0))
        self.b_hidden = np.ascontiguousarray(hidden[:, :, n_in].T)
        self.w_output = np.ascontiguousarray(output[:, :, :n_hid].transpose(2, 1, 0))
        self.b_output = np.ascontiguousarray(output[:, :, n_hid].T)
        self._buffers: dict[int, np.ndarray] = {}

    def take(self, trials: np.ndarray) -> None:
        """Keeps only ``trials`` (index array), in that order."""
        self.w_hidden = np.ascontiguousarray(self.w_hidden[..., trials])
        self.b_hidden = np.ascontiguousarray(self.b_hidden[..., trials])
        self.w_output = np.ascontiguousarray(self.w_output[..., trials])
        self.b_output = np.ascontiguousarray(self.b_output[..., trials])

    def forward(self, x: np.ndarray) -> np.ndarray:
        """Outputs (B, N, O) in [0, 1] for inputs ``x`` (B, N, I)."""
        xt = np.ascontiguousarray(x.transpose(2, 1, 0))
        if compiled.loaded():
            return self._forward_compiled(xt)
        h = _layer(xt, self.w_hidden, self.b_hidden)
        o = _layer(h, self.w_output, self.b_output)
        return o.transpose(2, 1, 0)

    def _forward_compiled(self, xt: np.ndarray) -> np.ndarray:
        """:meth:`forward` in three compiled passes around numpy's ``exp``.

        The passes do :func:`_layer`'s operations in its order: a layer's sums
        are negated as ``sigmoid`` negates them, numpy takes their ``exp`` in
        place (its own implementation, as a controller node's), and the next
        pass adds 1 and takes the reciprocal as ``sigmoid`` does before using the
        values, the last one writing the outputs robot-major. Between them, the
        hidden and output values live in buffers kept across steps, so a step
        allocates only its outputs.
        """
        n_robots, n_trials = xt.shape[1], xt.shape[2]
        hidden = self._buffer(0, (self.shape.n_hidden, n_robots, n_trials))
        output = self._buffer(1, (self.shape.n_outputs, n_robots, n_trials))
        _negated_sums(xt, self.w_hidden, self.b_hidden, hidden, False)
        np.exp(hidden, out=hidden)
        _negated_sums(hidden, self.w_output, self.b_output, output, True)
        np.exp(output, out=output)
        out = np.empty((n_trials, n_robots, self.shape.n_outputs))
        _logistic_robot_major(output, out)
        return out

    def _buffer(self, which: int, shape: tuple[int, int, int]) -> np.ndarray:
        """The scratch array ``which`` (0 hidden, 1 output) of ``shape``, kept
        until the batch's size changes."""
        buf = self._buffers.get(which)
        if buf is None or buf.shape != shape:
            buf = self._buffers[which] = np.empty(shape)
        return buf


def _layer(x: np.ndarray, w: np.ndarray, b: np.ndarray) -> np.ndarray:
    """sigma(b + sum_i w[i] x[i]), summed in index order, with numpy (a process
    without numba; :meth:`TeamNetworks._forward_compiled` does the same
    operations in compiled passes).

    Args:
        x: (I, N, B) source unit values per robot.
        w: (I, U, B) weights per trial.
        b: (U, B) biases per trial.

    Returns:
        (U, N, B) unit values.
    """
    a = np.repeat(b[:, None, :], x.shape[1], axis=1)
    tmp = np.empty_like(a)
    for i in range(w.shape[0]):
        np.multiply(w[i][:, None, :], x[i][None], out=tmp)
        a += tmp
    return sigmoid(a)


@compiled.compiled(
    "void(float64[:, :, ::1], float64[:, :, ::1], float64[:, ::1], float64[:, :, ::1], "
    "boolean)"
)
def _negated_sums(
    x: np.ndarray, w: np.ndarray, b: np.ndarray, out: np.ndarray, logistic: bool
) -> None:  # pragma: no cover - compiled; tested against the numpy form
    """``out[u, n, t] = -(b[u, t] + w[0, u, t] x[0, n, t] + w[1, u, t] x[1, n, t]
    + ...)``, added in that order (the numpy form of :func:`_layer`), then
    negated (``sigmoid``'s first operation, exact) while the row is in cache.

    With ``logistic``, ``x`` holds the previous layer's ``exp(-a)``: first the
    rest of its ``sigmoid``, ``1 / (x + 1)`` in place (its addition and its
    reciprocal)."""
    if logistic:
        flat = x.reshape(-1)
        for k in range(flat.shape[0]):
            flat[k] = 1.0 / (flat[k] + 1.0)
    n_trials = out.shape[2]
    n_in = w.shape[0]
    for u in range(out.shape[0]):
        for n in range(out.shape[1]):
            for t in range(n_trials):
                out[u, n, t] = b[u, t]
            # Four inputs per pass over the row, added left to right, so each
            # sum is the same sequence of roundings as one input per pass, with
            # a quarter of the row's loads and stores.
            i = 0
            while i + 4 <= n_in:
                for t in range(n_trials):
                    out[u, n, t] = (
                        out[u, n, t]
                        + w[i, u, t] * x[i, n, t]
                        + w[i + 1, u, t] * x[i + 1, n, t]
                        + w[i + 2, u, t] * x[i + 2, n, t]
                        + w[i + 3, u, t] * x[i + 3, n, t]
                    )
                i += 4
            while i < n_in:
                for t in range(n_trials):
                    out[u, n, t] += w[i, u, t] * x[i, n, t]
                i += 1
            for t in range(n_trials):
                out[u, n, t] = -out[u, n, t]


@compiled.compiled("void(float64[:, :, ::1], float64[:, :, ::1])")
def _logistic_robot_major(
    e: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - compiled; tested against the numpy form
    """The rest of ``sigmoid`` on the output layer's ``e = exp(-a)`` (U, N, B),
    ``1 / (e + 1)``, written robot-major into ``out`` (B, N, U)."""
    for u in range(e.shape[0]):
        for n in range(e.shape[1]):
            for t in range(e.shape[2]):
                out[t, n, u] = 1.0 / (e[u, n, t] + 1.0)


def forward(genome: np.ndarray, shape: NetworkShape, x: np.ndarray) -> np.ndarray:
    """Outputs (N, O) of one team's genome (W,) for its robots' inputs ``x``
    (N, I); the same arithmetic as :class:`TeamNetworks`, so a controller run
    live matches the batch bit for bit."""
    g = check_genomes(np.asarray(genome, dtype=np.float64)[None, :], shape)
    x = np.asarray(x, dtype=np.float64)
    return TeamNetworks(shape, g).forward(x[None])[0]
