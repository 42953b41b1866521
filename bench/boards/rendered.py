"""OpenCV's chessboard corners against the truth on rendered boards (bench/boards/README.md):
findChessboardCornersSB (default flags and NORMALIZE+EXHAUSTIVE+ACCURACY) and cornerSubPix
(15x15) on its corners, 12 rendered 9x6 boards (8x8 supersampled, blur sigma 1 px, noise 2/255).
"""
import cv2, numpy as np

rng=np.random.default_rng(1)
def render(H, ss=8, size=(640,480)):
    W,Hh=size
    ys,xs=np.mgrid[0:Hh*ss,0:W*ss]
    px=(xs+0.5)/ss-0.5; py=(ys+0.5)/ss-0.5
    Hi=np.linalg.inv(H)
    X=Hi[0,0]*px+Hi[0,1]*py+Hi[0,2]; Y=Hi[1,0]*px+Hi[1,1]*py+Hi[1,2]; Wd=Hi[2,0]*px+Hi[2,1]*py+Hi[2,2]
    u=X/Wd; v=Y/Wd  # board units (squares), inner corners at integer 1..9 x 1..6
    inside=(u>0)&(u<10)&(v>0)&(v<7)
    c=((np.floor(u)+np.floor(v))%2==0)
    img=np.where(inside, np.where(c,40,215), 128).astype(np.float32)
    return img.reshape(Hh,ss,W,ss).mean(axis=(1,3))
errs={'sb default':[],'sbacc':[],'sub7':[]}
for t in range(12):
    # random homography: board 10x7 squares, square ~ 30-45px, tilted
    s=rng.uniform(28,42); ang=rng.uniform(-0.5,0.5)
    A=np.array([[s*np.cos(ang),-s*np.sin(ang),320-5*s*np.cos(ang)+3.5*s*np.sin(ang)],[s*np.sin(ang),s*np.cos(ang),240-5*s*np.sin(ang)-3.5*s*np.cos(ang)],[0,0,1]])
    P=np.array([[1,0,0],[0,1,0],[rng.uniform(-4e-4,4e-4),rng.uniform(-4e-4,4e-4),1]])
    # apply perspective about centre
    T=np.array([[1,0,-320],[0,1,-240],[0,0,1.]]); H=np.linalg.inv(T)@P@T@A
    img=render(H)
    img=cv2.GaussianBlur(img,(0,0),1.0)+rng.normal(0,2,img.shape)
    g=np.clip(img,0,255).astype(np.uint8)
    truth=[]
    for j in range(1,7):
        for i in range(1,10):
            p=H@np.array([i,j,1.]); truth.append(p[:2]/p[2])
    truth=np.array(truth)
    for key,flags in (('sb default',0),('sbacc',cv2.CALIB_CB_ACCURACY|cv2.CALIB_CB_EXHAUSTIVE|cv2.CALIB_CB_NORMALIZE_IMAGE)):
        ok,c=cv2.findChessboardCornersSB(g,(9,6),flags=flags)
        if not ok: print('miss',key); continue
        c=c.reshape(-1,2)
        d=np.array([np.min(np.linalg.norm(truth-p,axis=1)) for p in c]); errs[key]+=list(d)
        if key=='sbacc':
            s5=cv2.cornerSubPix(g,c.reshape(-1,1,2).copy(),(7,7),(-1,-1),(3,100,1e-4)).reshape(-1,2)
            d=np.array([np.min(np.linalg.norm(truth-p,axis=1)) for p in s5]); errs['sub7']+=list(d)
for k,v in errs.items():
    v=np.array(v); print(k, len(v), 'rms vs truth %.3f max %.3f'%(np.sqrt((v**2).mean()), v.max()))
