"""PNG figures of plans, comparisons and sweeps (matplotlib, headless Agg backend)."""
from __future__ import annotations

import os

import matplotlib

matplotlib.use('Agg')  # no display on servers and CI
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def save_figure(fig, path):
    """Write ``fig`` as a PNG at ``path`` (folders made as needed), close it, return ``path``."""
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_plan(ev, path: str, keep_out=None):
    """Reference position, velocity, acceleration, jerk and the simulated swing of one plan; with a bridge also
    the out-of-plane swing and a top view (x-y) of the suspension point's and the load's paths; with
    ``keep_out`` boxes (a ``planning.keep_out.KeepOut``) both masses' paths beside them from the side (x-z)
    and from above (x-y)."""
    s, sim, plan = ev.samples, ev.sim, ev.plan
    spatial = 'phi1' in sim.states
    rows = 3 + spatial + bool(keep_out)
    fig, axes = plt.subplots(rows, 2, figsize=(11, 2.7 * rows))
    for ax, (y, label) in zip(axes.flat[:4], [(s.position, 'position (m)'), (s.velocity, 'velocity (m/s)'),
                                              (s.acceleration, 'acceleration (m/s²)'), (s.jerk, 'jerk (m/s³)')]):
        ax.plot(s.t, y, label='cart')
        ax.set_ylabel(label)
    if spatial:
        bridge = plan.evaluate_axis('bridge', s.t)
        for ax, y in zip(axes.flat[:4], (bridge.position, bridge.velocity, bridge.acceleration, bridge.jerk)):
            ax.plot(s.t, y, label='bridge')
        axes[0, 0].legend()
    axes[2, 0].plot(sim.t, sim.theta1[0], label='θ1')
    axes[2, 0].plot(sim.t, sim.theta2[0], label='θ2 (relative)')
    if spatial:
        axes[2, 0].plot(sim.t, sim.phi1[0], label='φ1')
        axes[2, 0].plot(sim.t, sim.phi2[0], label='φ2 (relative)')
    axes[2, 0].set_ylabel('swing (rad)')
    axes[2, 0].legend()
    axes[2, 1].plot(sim.t, 1e3 * sim.load_excursion[0])
    axes[2, 1].set_ylabel('load excursion (mm)' + (', norm' if spatial else ''))
    for ax in axes[:3].flat:  # the time plots share their axis (the top view has its own)
        if ax is not axes[0, 0]:
            ax.sharex(axes[0, 0])
        ax.axvline(plan.duration, color='k', lw=0.6, ls=':')
        ax.grid(True, alpha=0.3)
    axes[2, 0].set_xlabel('time (s)')
    axes[2, 1].set_xlabel('time (s)')
    if spatial:
        _plot_top_view(axes[3, 0], axes[3, 1], sim)
        title = f'({plan.displacement:g}, {plan.axes["bridge"].displacement:g}) m'
    else:
        title = f'{plan.displacement:g} m'
    if keep_out:
        _plot_keep_out(axes[-1, 0], axes[-1, 1], sim, keep_out)
    fig.suptitle(f'{plan.method.upper()}: {title} in {plan.duration:g} s')
    return save_figure(fig, path)


def _plot_keep_out(side_ax, top_ax, sim, keep_out):
    """Both masses' simulated paths beside the keep-out boxes (grey; dashed: grown by the margin), from the
    side (x-z) and from above (x-y)."""
    from matplotlib.patches import Rectangle

    from .evaluate import simulated_masses
    m1, m2 = simulated_masses(sim)
    for ax, (i, j), title in ((side_ax, (0, 2), 'side view (x-z)'), (top_ax, (0, 1), 'top view (x-y)')):
        for box in keep_out.boxes:
            lo, hi = np.maximum(box.lower, -1e3), np.minimum(box.upper, 1e3)
            ax.add_patch(Rectangle((lo[i], lo[j]), hi[i] - lo[i], hi[j] - lo[j], color='0.6', alpha=0.5))
            m = keep_out.margin
            ax.add_patch(Rectangle((lo[i] - m, lo[j] - m), hi[i] - lo[i] + 2 * m, hi[j] - lo[j] + 2 * m, fill=False,
                                   ls='--', color='0.4'))
        ax.plot(m1[i], m1[j], lw=1.0, label='upper mass m1')
        ax.plot(m2[i], m2[j], lw=1.2, label='load m2')
        span = np.concatenate([m1[[i, j]], m2[[i, j]]], axis=1)
        pad = 0.1 * max(np.ptp(span[0]), np.ptp(span[1]), 0.1)
        ax.set_xlim(span[0].min() - pad, span[0].max() + pad)
        ax.set_ylim(span[1].min() - pad, span[1].max() + pad)
        ax.set_xlabel('x, cart (m)')
        ax.set_ylabel('z (m)' if j == 2 else 'y, bridge (m)')
        ax.set_title(f'{title}: the keep-out boxes, the masses\' paths', fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)


def _plot_top_view(path_ax, zoom_ax, sim):
    """The spatial crane from above (x along the cart, y along the bridge): the suspension point's and the load's
    paths (``path_ax``), and the load's horizontal offset from below the suspension point in mm (``zoom_ax``)."""
    from crane_msgs_py.crane.geometry import load_offset
    L1 = sim.plants.L1[0] if sim.L1 is None else sim.L1[0]
    dx, dy = load_offset(sim.theta1[0], sim.theta2[0], sim.phi1[0], sim.phi2[0], L1, sim.plants.L2[0])
    x, y = sim.y[0], sim.yb[0]
    path_ax.plot(x, y, label='suspension point')
    path_ax.plot(x + dx, y + dy, lw=0.8, label='load')
    path_ax.set_xlabel('x, cart (m)')
    path_ax.set_ylabel('y, bridge (m)')
    path_ax.set_aspect('equal', adjustable='datalim')
    path_ax.set_title('top view', fontsize=10)
    path_ax.legend(fontsize=8)
    path_ax.grid(True, alpha=0.3)
    zoom_ax.plot(1e3 * dx, 1e3 * dy, lw=0.8)
    zoom_ax.set_xlabel('load offset x (mm)')
    zoom_ax.set_ylabel('load offset y (mm)')
    zoom_ax.set_aspect('equal', adjustable='datalim')
    zoom_ax.set_title('the load seen from the suspension point', fontsize=10)
    zoom_ax.grid(True, alpha=0.3)


def plot_compare(evaluations, path: str):
    """Velocity and acceleration per method (paper Figs. 2-3) and the load swing each leaves."""
    fig, axes = plt.subplots(3, 1, figsize=(9, 10), sharex=True)
    for ev in evaluations:
        label = ev.plan.method.upper()
        axes[0].plot(ev.samples.t, ev.samples.velocity, label=label)
        axes[1].plot(ev.samples.t, ev.samples.acceleration, label=label)
        axes[2].plot(ev.sim.t, 1e3 * ev.sim.load_excursion[0], label=label)
    axes[0].set_ylabel('reference velocity (m/s)')
    axes[1].set_ylabel('reference acceleration (m/s²)')
    axes[2].set_ylabel('load excursion (mm)')
    axes[2].set_xlabel('time (s)')
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(ncol=4, fontsize=8)
    if evaluations:
        p = evaluations[0].plan
        axes[0].set_title(f'{p.displacement:g} m in {p.duration:g} s')
    return save_figure(fig, path)


def plot_sweep(result: dict, path: str, nominal: float | None = None):
    """Residual load swing vs the varied plant parameter, one curve per method (paper Fig. 4)."""
    fig, ax = plt.subplots(figsize=(9, 5.5))
    values = np.asarray(result['values'])
    for method, r in result['methods'].items():
        ax.plot(values, r['load_mm'], marker='.', label=method.upper())
    if nominal is not None:
        ax.axvline(nominal, color='k', lw=0.6, ls=':')
    ax.set_xlabel(f'plant {result["param"]}')
    ax.set_ylabel('residual load swing (mm)')
    ax.grid(True, alpha=0.3)
    ax.legend()
    return save_figure(fig, path)


def plot_identification(recording, result, path: str):
    """Measured and fitted swing angles (mrad) of ``crane-plan identify``, and their difference."""
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    t = recording.t - recording.t[0]
    for ax, name, measured, fitted in ((axes[0], 'theta1', recording.theta1, result.theta1),
                                       (axes[1], 'theta2', recording.theta2, result.theta2)):
        ax.plot(t, 1e3 * measured, '.', ms=2.5, color='0.55', label='measured')
        ax.plot(t, 1e3 * fitted, lw=1.2, color='C0', label='fitted model')
        ax.set_ylabel(f'{name} (mrad)')
        ax.legend(loc='upper right', fontsize=8)
    axes[2].plot(t, 1e3 * (recording.theta1 - result.theta1), lw=0.8, label='theta1')
    axes[2].plot(t, 1e3 * (recording.theta2 - result.theta2), lw=0.8, label='theta2')
    axes[2].set_ylabel('residual (mrad)')
    axes[2].set_xlabel('time (s)')
    axes[2].legend(loc='upper right', fontsize=8)
    v = result.values
    axes[0].set_title(f'identified L1 {v["L1"]:.4f} m, L2 {v["L2"]:.4f} m, m2/(m1+m2) {v["mass_ratio"]:.3f}, '
                      f'zeta {v["zeta1"]:.4f} / {v["zeta2"]:.4f}; '
                      f'rms residual {1e3 * result.rms_residual_rad:.2f} mrad',
                      fontsize=9)
    return save_figure(fig, path)


def plot_choice(result, path: str):
    """``crane-plan choose``: worst residual over the band vs fastest duration per method, and the swing over L1."""
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4.8))
    ok = [c for c in result.candidates if c.duration is not None]
    for c in ok:
        chosen = c.method == result.chosen
        ax.scatter(c.duration, max(c.worst_residual_mm, 1e-3), s=90 if chosen else 40,
                   marker='*' if chosen else 'o', zorder=3)
        ax.annotate(c.method.upper() + (' (chosen)' if chosen else ''), (c.duration, max(c.worst_residual_mm, 1e-3)),
                    textcoords='offset points', xytext=(6, 4), fontsize=9)
    ax.axhline(result.tolerance_mm, color='k', lw=0.8, ls='--', label=f'tolerance {result.tolerance_mm:g} mm')
    ax.set_yscale('log')
    ax.set_xlabel('fastest duration within the limits (s)')
    ax.set_ylabel('worst residual load swing over the band (mm)')
    ax.set_title(f'{result.displacement:g} m: which method?', fontsize=10)
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(fontsize=8)
    L1 = np.array([a for a, _ in result.plants])
    for c in ok:
        order = np.argsort(L1, kind='stable')
        ax2.plot(L1[order], np.maximum(np.array(c.residual_mm)[order], 1e-3), '.-', ms=3, label=c.method.upper())
    ax2.axhline(result.tolerance_mm, color='k', lw=0.8, ls='--')
    ax2.set_yscale('log')
    ax2.set_xlabel('plant L1 (m)')
    ax2.set_ylabel('residual load swing (mm)')
    ax2.set_title('at each method\'s fastest duration', fontsize=10)
    ax2.grid(True, which='both', alpha=0.3)
    ax2.legend(fontsize=8, ncol=2)
    return save_figure(fig, path)
