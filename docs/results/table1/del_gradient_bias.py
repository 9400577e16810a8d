#!/usr/bin/python3
"""Where DEL's gradient points, against RP's and LR's, on one trial snapshot.

    del_gradient_bias.py 'del-bias/r100_ep{ep}_{m}.json' 15
    del_gradient_bias.py 'del-bias/ep{ep}_{m}.json' 1

Each file is `totalgrad bench gradients --snapshot S --episode EP --method M
--replicates R --out FILE` (R estimates with fixed random numbers). RP and LR
are unbiased estimators of the same gradient of the model's expected cost, so
their mean gradients should agree up to Monte Carlo error; DEL is biased
(an LR gradient at a Gaussian fitted to the particles). Prints, per method,
the norm of the mean gradient, the relative Monte Carlo standard error of one
estimate, and the cosine between its mean gradient and RP's and LR's.
"""
import json
import sys

import numpy as np


def main():
    pattern = sys.argv[1]
    episodes = [int(e) for e in sys.argv[2].split(",")]
    for episode in episodes:
        means, rel_se, info = {}, {}, None
        for method in ("RP", "LR", "DEL"):
            doc = json.load(open(pattern.format(ep=episode, m=method)))
            g = np.array(doc["gradients"], dtype=float)
            means[method] = g.mean(axis=0)
            rel_se[method] = np.sqrt(((g - means[method]) ** 2).sum(axis=1).mean()) / np.linalg.norm(means[method])
            info = doc
        print(f"episode {episode}: N = {info['gp_data']}, P = {info['particles']}, "
              f"H = {info['horizon']}, R = {info['replicates']} ({info['source']})")
        for method in ("RP", "LR", "DEL"):
            m = means[method]
            cos = {ref: float(m @ means[ref] / np.linalg.norm(m) / np.linalg.norm(means[ref])) for ref in ("RP", "LR")}
            print(f"  {method:4s} |mean g| {np.linalg.norm(m):8.4g}  rel_SE {rel_se[method]:6.3f}  "
                  f"cos with RP {cos['RP']:+.3f}  cos with LR {cos['LR']:+.3f}")


if __name__ == "__main__":
    main()
