"""Reproduces the gold-polyimide fits of Eq. 4 and Cook-Torrance in docs/brdf.md.

Pure Python (stdlib only). Usage: python3 docs/brdf_fit.py bp|ct
Fits each model to the paper's Eq. 5 curve (in plane, theta_i = 30 and 60 deg,
theta_v in [-89, 89] step 0.25) by Nelder-Mead; prints parameters, objective, RMSE 30/60.
"""
import math
PI=math.pi
def half(wo,wi):
    v=[wo[0]+wi[0],wo[1]+wi[1],wo[2]+wi[2]]
    l2=sum(c*c for c in v); l=math.sqrt(l2)
    s2=(v[0]**2+v[1]**2)/l2
    return [c/l for c in v], v[2]/l, s2, 0.5*l
def imp(wo,wi,rd,rs,al,a,b):
    if wo[2]<=0 or wi[2]<=0: return 0.0
    h,c,s2,d=half(wo,wi)
    lc=0.5*math.log1p(-s2)
    omc=s2/(1+c)
    fall=math.exp(-b*omc**(1/PI)) if b>0 else 1.0
    return rd/PI + rs*math.exp(al*lc)*fall/wi[2]**a
def ct(wo,wi,rd,m,f0,ks=1.0):
    if wo[2]<=0 or wi[2]<=0: return 0.0
    h,c,s2,d=half(wo,wi)
    tan2=s2/(c*c); e=tan2/(m*m)
    D=math.exp(-e)/(PI*m*m*c**4) if e<80 else 0.0
    def g1(v):
        s=math.hypot(v[0],v[1])
        if s==0: return 1.0
        a=v[2]/(m*s)
        return 1.0 if a>=1.6 else (3.535*a+2.181*a*a)/(1+2.276*a+2.577*a*a)
    F=f0+(1-f0)*(1-d)**5
    return rd/PI + ks*D*g1(wo)*g1(wi)*F/(4*wo[2]*wi[2])
def dirs(ti,tv):
    ti=math.radians(ti); tv=math.radians(tv)
    wi=(math.sin(ti),0.0,math.cos(ti)); wo=(-math.sin(tv),0.0,math.cos(tv))
    return wo,wi
GOLD=(0.3717,283.9,3865.7,0.9665,1.3965)
VIEWS=[-89+0.25*k for k in range(int(178/0.25)+1)]
def rmse(f,ti):
    s=0;n=0
    for tv in VIEWS:
        wo,wi=dirs(ti,tv)
        r=imp(wo,wi,*GOLD); m=f(wo,wi)
        s+=(r-m)**2; n+=1
    return math.sqrt(s/n)
def obj(f): return math.sqrt((rmse(f,30)**2+rmse(f,60)**2)/2)
def nm(fun,x0,step,it=400):
    n=len(x0); pts=[list(x0)]
    for i in range(n):
        p=list(x0); p[i]+=step[i]; pts.append(p)
    vals=[fun(p) for p in pts]
    for _ in range(it):
        o=sorted(range(n+1),key=lambda i:vals[i]); pts=[pts[i] for i in o]; vals=[vals[i] for i in o]
        c=[sum(p[j] for p in pts[:-1])/n for j in range(n)]
        xr=[c[j]+(c[j]-pts[-1][j]) for j in range(n)]; fr=fun(xr)
        if fr<vals[0]:
            xe=[c[j]+2*(c[j]-pts[-1][j]) for j in range(n)]; fe=fun(xe)
            if fe<fr: pts[-1],vals[-1]=xe,fe
            else: pts[-1],vals[-1]=xr,fr
        elif fr<vals[-2]: pts[-1],vals[-1]=xr,fr
        else:
            xc=[c[j]+0.5*(pts[-1][j]-c[j]) for j in range(n)]; fc=fun(xc)
            if fc<vals[-1]: pts[-1],vals[-1]=xc,fc
            else:
                for i in range(1,n+1):
                    pts[i]=[pts[0][j]+0.5*(pts[i][j]-pts[0][j]) for j in range(n)]; vals[i]=fun(pts[i])
    o=min(range(n+1),key=lambda i:vals[i]); return pts[o],vals[o]
import sys
which=sys.argv[1]
if which=='bp':
    f=lambda p: obj(lambda wo,wi: imp(wo,wi,0.3717,p[0],p[1],1.0,0.0)) if p[0]>0 and p[1]>1 else 1e9
    x,v=nm(f,[280,3000],[30,500],300)
    print('bp',x,v, rmse(lambda wo,wi: imp(wo,wi,0.3717,x[0],x[1],1,0),30), rmse(lambda wo,wi: imp(wo,wi,0.3717,x[0],x[1],1,0),60))
elif which=='ct':
    f=lambda p: obj(lambda wo,wi: ct(wo,wi,0.3717,p[0],p[1])) if 0.001<p[0]<1 and 0<=p[1]<=1 else 1e9
    x,v=nm(f,[0.02,0.8],[0.003,0.1],300)
    print('ct',x,v, rmse(lambda wo,wi: ct(wo,wi,0.3717,x[0],x[1]),30), rmse(lambda wo,wi: ct(wo,wi,0.3717,x[0],x[1]),60))
elif which=='ctks':
    f=lambda p: obj(lambda wo,wi: ct(wo,wi,0.3717,p[0],p[1],p[2])) if 0.001<p[0]<1 and 0<=p[1]<=1 and p[2]>0 else 1e9
    x,v=nm(f,[0.02,0.8,1.0],[0.003,0.1,0.2],400)
    print('ctks',x,v)
print('imp self', rmse(lambda wo,wi: imp(wo,wi,*GOLD),30))
