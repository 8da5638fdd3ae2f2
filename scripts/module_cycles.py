#!/usr/bin/env python3
"""Fails when two modules of a crate import each other, directly or through others
(docs/architecture.md: the layers only point one way). Reads `crate::…` and `super::…`
paths outside `#[cfg(test)]`; a parent module's own declarations do not count. Every
crate of the workspace is checked (the crates themselves cannot form cycles: Cargo refuses).
Usage: python3 scripts/module_cycles.py [DEPTH] (module path depth, default 4: files)."""
import re,os,collections,sys
os.chdir(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))
depth=int(sys.argv[1]) if len(sys.argv)>1 else 4
SOURCES=['src','crates/reflectance-core/src','crates/reflectance-render/src']

def cycles(source):
  mods={}
  for root,_,files in os.walk(source):
      for f in files:
          if not f.endswith('.rs'): continue
          p=os.path.join(root,f); rel=p[len(source)+1:-3]
          parts=[x for x in rel.split('/') if x!='mod']
          if parts in (['lib'],['main']): continue
          mods['::'.join(parts)]=p
  def key(path):
      parts=path.split('::')
      # longest known module prefix
      for n in range(len(parts),0,-1):
          k='::'.join(parts[:n])
          if k in mods: return '::'.join(parts[:min(n,depth)])
      return None
  edges=collections.defaultdict(set)
  for m,p in mods.items():
      src=open(p).read()
      i=src.find('#[cfg(test)]')
      if i>=0: src=src[:i]
      me='::'.join(m.split('::')[:depth])
      parent='::'.join(m.split('::')[:-1])
      refs=[]
      for mm in re.finditer(r'crate::([\w:]+)',src): refs.append(mm.group(1))
      for mm in re.finditer(r'use crate::\{([^;]*)\};',src,re.S):
          for t in re.findall(r'([\w:]+)',mm.group(1)): refs.append(t)
      for mm in re.finditer(r'(?:use )?super::([\w:]+)',src):
          refs.append((parent+'::' if parent else '')+mm.group(1))
      for mm in re.finditer(r'use super::\{([^;]*)\};',src,re.S):
          for t in re.findall(r'([\w:]+)',mm.group(1)): refs.append((parent+'::' if parent else '')+t)
      for r in refs:
          k=key(r.strip(':'))
          if k and k!=me and not me.startswith(k+'::') : edges[me].add(k)
  def reach(a):
      seen=set(); st=[a]
      while st:
          x=st.pop()
          for y in edges.get(x,()):
              if y not in seen: seen.add(y); st.append(y)
      return seen
  found=set()
  for a in sorted(edges):
      for b in sorted(edges[a]):
          if a in reach(b): found.add(tuple(sorted((a,b))))
  for c in sorted(found): print('CYCLE',source,c)
  print(len(found),'import cycles among the modules of %s/ (depth %d)' % (source, depth))
  return len(found)

sys.exit(1 if sum(cycles(s) for s in SOURCES) else 0)
