// N threads busy-reading CLOCK_MONOTONIC for D seconds; reports gaps > 1 ms per thread.
#define _GNU_SOURCE
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
static double now(void){struct timespec t;clock_gettime(CLOCK_MONOTONIC,&t);return t.tv_sec+t.tv_nsec*1e-9;}
static double dur; static int prio;
typedef struct {int id; double max; int n1; int n01; double t0;} R;
static void* run(void*a){R*r=a; if(prio>0){struct sched_param p={.sched_priority=prio}; if(pthread_setschedparam(pthread_self(),SCHED_FIFO,&p)) {perror("fifo");}}
 double t0=now(),last=t0; r->t0=t0; while(1){double t=now(); double g=t-last; if(g>r->max)r->max=g; if(g>1e-3){r->n1++; if(r->n1<=40) printf("  thread %d t=%.3f gap %.2f ms\n",r->id,t-t0,g*1e3);} else if(g>1e-4) r->n01++; last=t; if(t-t0>dur)break;} return 0;}
int main(int c,char**v){int n=atoi(v[1]); dur=atof(v[2]); prio=c>3?atoi(v[3]):0; pthread_t th[8]; R r[8]={0};
 for(int i=0;i<n;i++){r[i].id=i;pthread_create(&th[i],0,run,&r[i]);} for(int i=0;i<n;i++)pthread_join(th[i],0);
 for(int i=0;i<n;i++)printf("thread %d: max gap %.2f ms, gaps>1ms %d, 0.1-1ms %d\n",i,r[i].max*1e3,r[i].n1,r[i].n01); return 0;}
