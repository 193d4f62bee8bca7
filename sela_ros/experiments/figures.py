"""Figures of the experiments (matplotlib, Agg backend; imported only when plotting)."""
from __future__ import annotations

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

LABELS = {'sela': 'SELA', 'random_babbling': 'random\nbabbling', 'ite_4dir': 'IT&E\n4 dirs',
          'ite_uncertainty': 'IT&E\nuncertainty', 'oracle': 'oracle'}


def plot_methods(doc: dict, path, title: str | None = None) -> None:
    """Per method: box plots of learning iterations and task steps, as in the paper.

    Args:
        doc: a ``results.json`` document.
        path: output image path (PNG).
        title: figure title (default: scenario, replicates, noise).
    """
    names = list(doc['methods'])
    fig, ax = plt.subplots(figsize=(6.4, 3.6), dpi=100)
    width = 0.35
    x = np.arange(len(names))
    for offset, key, colour, label in ((-width / 2, 'learning_iterations', '#d95f02',
                                        'learning iterations'),
                                       (width / 2, 'steps', '#1b9e77', 'task steps')):
        data = [doc['methods'][n][key] for n in names]
        bp = ax.boxplot(data, positions=x + offset, widths=width * 0.9, patch_artist=True,
                        showfliers=True, flierprops={'markersize': 3})
        for box in bp['boxes']:
            box.set_facecolor(colour)
            box.set_alpha(0.7)
        for median in bp['medians']:
            median.set_color('black')
        ax.plot([], [], 's', color=colour, alpha=0.7, label=label)
    ticks = []
    for n in names:
        ok = sum(doc['methods'][n]['success'])
        ticks.append(f'{LABELS.get(n, n)}\n({ok}/{len(doc["methods"][n]["success"])})')
    ax.set_xticks(x)
    ax.set_xticklabels(ticks, fontsize=8)
    ax.set_ylabel('iterations (atomic behaviours)')
    ax.grid(axis='y', alpha=0.3)
    ax.legend(fontsize=8, loc='upper left')
    if title is None:
        noise = doc.get('parameters', {}).get('noise_std')
        title = f'{doc["scenario"]}: {doc["replicates"]} replicates'
        if noise is not None:
            title += f', observation noise std {noise:g}'
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_noise_comparison(docs: list, path) -> None:
    """Side-by-side figure of several results documents (e.g. two noise levels)."""
    fig, axes = plt.subplots(1, len(docs), figsize=(5.2 * len(docs), 3.6), dpi=90,
                             sharey=True)
    axes = np.atleast_1d(axes)
    for ax, doc in zip(axes, docs):
        names = list(doc['methods'])
        x = np.arange(len(names))
        for offset, key, colour in ((-0.18, 'learning_iterations', '#d95f02'),
                                    (0.18, 'steps', '#1b9e77')):
            bp = ax.boxplot([doc['methods'][n][key] for n in names], positions=x + offset,
                            widths=0.3, patch_artist=True, flierprops={'markersize': 2})
            for box in bp['boxes']:
                box.set_facecolor(colour)
                box.set_alpha(0.7)
            for median in bp['medians']:
                median.set_color('black')
        ax.set_xticks(x)
        ax.set_xticklabels([f'{LABELS.get(n, n)}\n({sum(doc["methods"][n]["success"])}/'
                            f'{doc["replicates"]})' for n in names], fontsize=7)
        ax.set_title(f'noise std {doc["parameters"]["noise_std"]:g}', fontsize=9)
        ax.grid(axis='y', alpha=0.3)
    axes[0].set_ylabel('iterations (atomic behaviours)')
    axes[0].plot([], [], 's', color='#d95f02', alpha=0.7, label='learning iterations')
    axes[0].plot([], [], 's', color='#1b9e77', alpha=0.7, label='task steps')
    axes[0].legend(fontsize=7, loc='upper left')
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_course_paths(doc: dict, grid, path) -> None:
    """One panel per method: every replicate's walked path drawn over the course map.

    Args:
        doc: a ``results.json`` document of ``sela-experiment hexapod --map``.
        grid: the course's occupancy grid.
        path: output image path (PNG).
    """
    names = list(doc['methods'])
    xmin, xmax, ymin, ymax = grid.bounds
    fig, axes = plt.subplots(1, len(names), figsize=(3.3 * len(names), 3.6), dpi=100,
                             squeeze=False)
    for ax, name in zip(axes[0], names):
        m = doc['methods'][name]
        ax.imshow(grid.occupied, origin='lower', extent=(xmin, xmax, ymin, ymax),
                  cmap='Greys', vmin=0, vmax=1.4, interpolation='nearest')
        for walked, ok in zip(m['paths'], m['success']):
            xy = np.asarray(walked)
            ax.plot(xy[:, 0], xy[:, 1], lw=0.7, alpha=0.6,
                    color='#1b9e77' if ok else '#d95f02')
        ax.add_patch(plt.Circle(doc['parameters']['goal'], 0.1, color='tab:blue', fill=False,
                                lw=1))
        ax.plot(0, 0, 'ks', ms=4)
        s = doc['summary'][name]
        ax.set_title(f'{LABELS.get(name, name).replace(chr(10), " ")}: {s["successes"]}/'
                     f'{doc["replicates"]} reached\nmedian {s["median_steps"]:g} steps, '
                     f'{s["collisions"]} collisions', fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_aspect('equal')
    params = doc['parameters']
    fig.suptitle(f'course {params.get("course") or params.get("map")}, damage '
                 f'{params["damage"]}: walked paths (green: goal reached, orange: not)',
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
