"""Before/after table of the VP seed sweep, paired by seed: stop 20's runs against stop 23's (python scripts/intersection_before_after.py)."""
import pandas as pd, json, glob, numpy as np
def load(d): return pd.DataFrame([json.load(open(f)) for f in glob.glob(d+'/runs/*.json')])
old=pd.concat([load('results/intersection/seed_sweep_stop20')])
old=old[old.method.isin(['multi-vp','single-vp'])]
for name,d,seeds in [("dev 0-19","results/intersection/seed_sweep_stop23",range(20)),("held out 20-29","results/intersection/seed_sweep_stop23_heldout",range(20,30))]:
    new=load(d); o=old[old.seed.isin(list(seeds))]
    m=new.merge(o,on=['method','throughput','seed'],suffixes=('','_o'))
    print("###",name, len(m))
    print("| demand | method | jammed before -> after | jammed veh-s | mean speed [m/s] | fluctuation [m/s^2] | mean delay [s] | PET p05 [s] | min PET [s] |")
    print("|---:|---|---|---|---|---|---|---|---|")
    for (tp,meth),g in m.groupby(['throughput','method']):
        def pair(c,fmt):
            dd=g[c]-g[c+'_o']; n=len(dd); se=dd.std(ddof=1)/np.sqrt(n); from scipy.stats import t; h=t.ppf(.975,n-1)*se
            return (fmt%g[c+'_o'].mean())+" -> "+(fmt%g[c].mean())+(" (%+"+fmt[1:]+" ± "+fmt+")")%(dd.mean(),h)
        print(f"| {tp:g} | {meth} | {g.jammed_o.sum()} -> {g.jammed.sum()} | {g.jammed_vehicle_seconds_o.sum():.0f} -> {g.jammed_vehicle_seconds.sum():.0f} | {pair('mean_speed','%.2f')} | {pair('speed_fluctuation','%.3f')} | {pair('mean_delay','%.2f')} | {pair('pet_p05','%.2f')} | {g.pet_min_o.min():.2f} -> {g.pet_min.min():.2f} |")
