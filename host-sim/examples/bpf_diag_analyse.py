"""Per-frame analysis of `bpf_diag` output directories (diagnosis of the BPF bench, issue 19).

Usage: python3 host-sim/examples/bpf_diag_analyse.py 'GLOB_OF_DIRS' [NAME_TO_LIST]
Per directory: frame categories of the first reported group (ok_mean: within 2 Hz of a rotor's
Hann^2-weighted true BPF; ok_ref_only: within 2 Hz only of a rotor's isolated-sound peak;
in_cluster, octave, shaft_multiple, other, none), the within-window spread of the true BPF, and
how far each rotor's own rendered sound's spectral peak (Hann, 0.512 s, 16x zero padding) lies
from its true BPF.
"""
import numpy as np, sys, os, glob
FS=16000
def load(d):
    rot=np.loadtxt(d+'/rotors.csv',delimiter=',')
    frames=[]
    for line in open(d+'/frames.csv'):
        p=line.strip().split(',')
        frames.append((float(p[0]),[float(x) for x in p[1:] if x]))
    nr=rot.shape[1]-1
    rs=[np.fromfile(d+f'/rotor{i}.f32',dtype=np.float32) for i in range(nr)]
    return rot,frames,rs
def peak_ref(x,t,f0,win=0.512,pad=16):
    n=int(win*FS); s=int(round((t-win/2)*FS))
    if s<0 or s+n>len(x): return np.nan
    seg=x[s:s+n]*np.hanning(n)
    N=n*pad; X=np.abs(np.fft.rfft(seg,N)); fr=np.arange(len(X))*FS/N
    m=(fr>f0*0.93)&(fr<f0*1.07)
    return fr[m][np.argmax(X[m])]

tot={}
for d in sorted(glob.glob(sys.argv[1] if len(sys.argv)>1 else '/tmp/bpfdiag/*-s*')):
    name=os.path.basename(d); B=3 if ('3blade' in name) else 2
    rot,frames,rs=load(d)
    cats={}; spreads=[]; refdiff=[]; refmiss=0
    rows=[]
    for t,g in frames[2:]:
        m=(rot[:,0]>=t-0.256)&(rot[:,0]<=t+0.256)
        w=np.hanning(m.sum())**2
        tr=B*rot[m,1:]
        mean=tr.mean(0); wmean=(tr*w[:,None]).sum(0)/w.sum(); spread=tr.max(0)-tr.min(0)
        spreads+=list(spread)
        ref=np.array([peak_ref(rs[i],t,wmean[i]) for i in range(len(rs))])
        refdiff+=list(ref-mean)
        if not g: c='none'
        else:
            f=g[0]
            if np.any(abs(f-mean)<=2): c='ok_mean'
            elif np.any(abs(f-ref)<=2): c='ok_ref_only'
            elif mean.min()-2<=f<=mean.max()+2: c='in_cluster'
            elif any(np.any(abs(f-k*mean)<=0.02*k*mean) for k in (0.5,1/3,2,3)): c='octave'
            elif any(np.any(abs(f-k*mean/B)<=0.02*k*mean/B) for k in range(1,4*B)): c='shaft_multiple'
            else: c='other'
        cats[c]=cats.get(c,0)+1
        rows.append((t,g[:3],mean.round(1),c))
    n=len(frames)-2
    sp=np.array(spreads); rd=np.abs(np.array(refdiff))
    print(f"{name:32s} n={n} "+" ".join(f"{k}={v}" for k,v in sorted(cats.items()))+
          f" | spread med {np.median(sp):.1f} p90 {np.percentile(sp,90):.1f} Hz | |ref-mean| med {np.nanmedian(rd):.2f} p90 {np.nanpercentile(rd,90):.2f} frac>2Hz {np.nanmean(rd>2):.2f}")
    if len(sys.argv)>2 and sys.argv[2] in name:
        for r in rows: print('   ',r)
