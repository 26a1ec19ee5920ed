#!/usr/bin/env python3
# The two summary tables of bench/RESULTS.md's issue-17 rounds from a results directory that
# `stlrefine_fidelity --cad-families ... --out DIR` wrote: python3 summarize_cad.py DIR
import os, sys
fams=['cylinder','cone','tube','torus','sphere','ellipsoid','blob','rounded-box','plate']
rows={}
D=sys.argv[1] if len(sys.argv)>1 else '.'
for f in fams:
    p=f'{D}/{f}.md'
    if not os.path.exists(p): continue
    for line in open(p):
        c=[x.strip() for x in line.strip().strip('|').split('|')]
        if len(c)==14 and c[1].isdigit():
            rows[(f,c[0],int(c[1]))]=c
def g(f,s,L,i):
    r=rows.get((f,s,L)); return r[i] if r else '-'
print("| family | lsf L2 ×ideal / ×input | butterfly L2 ×input | sqrt3-interp L2 ×input | sqrt3-unified L2 ×input | seeds worse than input (interp. schemes, L1-3) |")
print("|---|--:|--:|--:|--:|--:|")
for f in fams:
    if not any(k[0]==f for k in rows): continue
    worse=0
    for s in ['lsf','butterfly','sqrt3-interp','sqrt3-unified','butterfly-g1']:
        for L in (1,2,3):
            v=g(f,s,L,7)
            if v!='-': worse+=int(v)
    print(f"| {f} | {g(f,'lsf',2,8)} / {g(f,'lsf',2,5)} | {g(f,'butterfly',2,5)} | {g(f,'sqrt3-interp',2,5)} | {g(f,'sqrt3-unified',2,5)} | {worse} |")
print()
schemes=['lsf','butterfly','sqrt3-interp','sqrt3-unified','butterfly-g1','loop']
print("| family | "+" | ".join(schemes)+" |")
print("|---|"+"--:|"*(len(schemes)))
for f in fams:
    if not any(k[0]==f for k in rows): continue
    cells=['/'.join(g(f,s,L,11).split(' ')[0] for L in (1,2,3)) for s in schemes]
    print(f"| {f} | "+" | ".join(cells)+" |")
