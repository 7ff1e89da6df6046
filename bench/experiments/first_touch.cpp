// The cost of simulate's result memory on first touch (bench/LOG.md, python-comparison
// section): ten fresh anonymous mappings shaped like simulate's results for 1e6 steps (state
// 12 doubles as before u_cmd, 7 doubles, 3 features, an int32 status: 180 bytes per step), written step by
// step as simulate does, 5 repetitions, ns per step. Not built by CMake; a scratch experiment:
//   g++ -O2 -mavx2 bench/experiments/first_touch.cpp -o first_touch && ./first_touch MODE
// MODE 0: 4 KiB pages; 1: MADV_HUGEPAGE; 2: MAP_POPULATE (4 KiB) before the timed writes;
// 3: 4 KiB pages, the state by non-temporal stores; 4: huge pages, results staged 8 steps at a
// time and copied by non-temporal stores; 5: the same by memcpy; 6: huge pages, one byte per
// 4 KiB (the kernel's zeroing alone); 7: huge pages, memset; 8: one huge-page mapping for all ten;
// 9: as 8 with MADV_POPULATE_WRITE before the timed writes.
#include <sys/mman.h>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <cstdlib>
#include <immintrin.h>
using C=std::chrono::steady_clock;
int main(int argc,char**argv){
  const long n=1000000; const int mode=atoi(argv[1]);
  // 20 streams: state 12 doubles/step, 7 x 1 double, feats 3 doubles, status int
  size_t sizes[10]={n*96, n*8,n*8,n*8,n*8,n*8,n*8,n*8, n*24, n*4};
  for(int rep=0;rep<5;++rep){
    auto t0=C::now();
    char* p[10];
    if(mode==8||mode==9){ size_t tot=0; for(int i=0;i<10;++i) tot+=sizes[i]; char* b=(char*)mmap(nullptr,tot+(2<<20),PROT_READ|PROT_WRITE,MAP_PRIVATE|MAP_ANONYMOUS,-1,0); madvise(b,tot+(2<<20),MADV_HUGEPAGE); if(mode==9) madvise(b, tot, 23 /*MADV_POPULATE_WRITE*/); size_t o=0; for(int i=0;i<10;++i){ p[i]=b+o; o+=sizes[i]; } } else
    for(int i=0;i<10;++i){ p[i]=(char*)mmap(nullptr,sizes[i],PROT_READ|PROT_WRITE,MAP_PRIVATE|MAP_ANONYMOUS|(mode==2?MAP_POPULATE:0),-1,0);
      if(mode==1||mode>=4) madvise(p[i],sizes[i],MADV_HUGEPAGE); }
    auto t1=C::now();
    double s[12]={1,2,3,4,5,6,7,8,9,10,11,12};
    if(mode==6){ for(int i=0;i<10;++i) for(size_t b=0;b<sizes[i];b+=4096) p[i][b]=1; } else if(mode==7){ for(int i=0;i<10;++i) memset(p[i],1,sizes[i]); } else
    if(mode>=4){
      alignas(64) double st[8*12], col[7][8], fe[8*3]; alignas(64) int stt[16];
      for(long k0=0;k0<n;k0+=8){
        for(int kk=0;kk<8;++kk){ long k=k0+kk; memcpy(st+kk*12,s,96); for(int i=1;i<8;++i) col[i-1][kk]=s[i]+k; memcpy(fe+kk*3,s,24); stt[kk]=0; s[0]+=1; }
        auto cp=[&](char* dst, const void* src, int bytes){ if(mode==4){ for(int b=0;b<bytes;b+=32) _mm256_stream_si256((__m256i*)(dst+b), _mm256_load_si256((const __m256i*)((const char*)src+b))); } else memcpy(dst,src,bytes);};
        cp(p[0]+k0*96, st, 768);
        for(int i=1;i<8;++i) cp(p[i]+k0*8, col[i-1], 64);
        cp(p[8]+k0*24, fe, 192);
        if(k0%16==0) {} memcpy(p[9]+k0*4, stt, 32);
      }
      _mm_sfence();
    } else
    for(long k=0;k<n;++k){
      if(mode==3){ for(int j=0;j<12;j+=4) _mm256_stream_pd((double*)p[0]+k*12+j, _mm256_loadu_pd(s+j)); }
      else memcpy(p[0]+k*96, s, 96);
      for(int i=1;i<8;++i) ((double*)p[i])[k]=s[i]+k;
      memcpy(p[8]+k*24, s, 24);
      ((int*)p[9])[k]=0;
      s[0]+=1;
    }
    auto t2=C::now();
    if(mode==8||mode==9){ size_t tot=0; for(int i=0;i<10;++i) tot+=sizes[i]; munmap(p[0],tot+(2<<20)); } else for(int i=0;i<10;++i) munmap(p[i],sizes[i]);
    printf("mode %d: alloc %.1f ns/step, write %.1f ns/step\n", mode, std::chrono::duration<double,std::nano>(t1-t0).count()/n, std::chrono::duration<double,std::nano>(t2-t1).count()/n);
  }
}
