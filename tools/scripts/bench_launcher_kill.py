#!/usr/bin/env python3
"""kill -9 of `exo run`: how long until every service it started has stopped.

Runs the default run file (lockstep, a 3000 s rest so the protocol outlasts
the measurement, services logging nothing) 20 times from the repository
root after `cargo build --release --workspace`, kills `exo run` 1 s after
its five services appear, and times until none runs (zombies count as
stopped). Prints p50 and the maximum in ms."""
import subprocess, time, os, tempfile, re, statistics
root=os.getcwd()
lat=[]
for i in range(20):
    d=tempfile.mkdtemp()
    t=open("configs/default.toml").read()
    t=t.replace('"plants/',f'"{root}/configs/plants/').replace('"subjects/',f'"{root}/configs/subjects/').replace('"experiments.toml"',f'"{root}/configs/experiments.toml"').replace('instance = "exo"',f'instance = "kb{i}"').replace('output_dir = "out/runs"',f'output_dir = "{d}"').replace("rest_s = 1.0","rest_s = 3000.0")
    open(f"{d}/run.toml","w").write(t)
    p=subprocess.Popen(["target/release/exo","run",f"{d}/run.toml"],stdout=subprocess.DEVNULL,stderr=subprocess.DEVNULL,env=dict(os.environ,RUST_LOG="off"))
    kids=[]
    t0=time.time()
    while len(kids)<5 and time.time()-t0<30:
        time.sleep(0.05)
        kids=[int(x) for x in subprocess.run(["pgrep","-P",str(p.pid)],capture_output=True,text=True).stdout.split()]
    time.sleep(1.0)
    p.kill(); t1=time.perf_counter(); p.wait()
    def alive(k):
        try:
            s=open(f"/proc/{k}/stat").read(); return s.rsplit(")",1)[1].split()[0]!="Z"
        except FileNotFoundError: return False
    while any(alive(k) for k in kids) and time.perf_counter()-t1<10: time.sleep(0.001)
    lat.append((time.perf_counter()-t1)*1000)
lat.sort()
print("n",len(lat),"p50 %.1f ms"%statistics.median(lat),"p99/max %.1f ms"%lat[-1], [round(x,1) for x in lat])
